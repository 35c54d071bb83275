"""What every engine run shares (the perturbed packing of a chaos rerun) and the engine registry: a new engine's
name is offered wherever an engine is chosen, and every driver provides what the registry asks for."""

import argparse
import contextlib
from pathlib import Path

import numpy as np
import pytest

from generators import cli, config, dem, engine, engines, scenes

ROOT = Path(__file__).resolve().parents[2]


def test_perturbation_moves_only_moving_particles_by_the_given_radii_and_repeats():
    rng = np.random.default_rng(0)
    packing = dem.Particles(rng.uniform(0, 1, (400, 2)), rng.uniform(0.01, 0.02, 400), np.r_[np.zeros(100, int),
                                                                                             np.ones(300, int)])
    a = engine.perturbed(packing, (0,), 1e-3, seed=7)
    b = engine.perturbed(packing, (0,), 1e-3, seed=7)
    np.testing.assert_array_equal(a.x, b.x)                               # seeded by the row's seed
    np.testing.assert_array_equal(a.x[:100], packing.x[:100])             # kinematic particles stay put
    step = (a.x[100:] - packing.x[100:]) / packing.radius[100:, None]
    assert abs(step.std() - 1e-3) < 1e-4 and abs(step.mean()) < 2e-4       # N(0, 1e-3 radii) per axis
    assert not np.array_equal(engine.perturbed(packing, (0,), 1e-3, seed=8).x, a.x)


FAKE = "fakedem"


@contextlib.contextmanager
def registered(name: str):
    """Engine ``name`` in the registry while the block runs (a name only: no package, no driver, nothing is
    run); the schema's cache is emptied on the way in and out, so nothing outside the block sees it."""
    try:
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(engines, "NAMES", (*engines.NAMES, name))
            config.schema.cache_clear()
            yield
    finally:
        config.schema.cache_clear()


def _engine_options(parser: argparse.ArgumentParser, real: list[str]) -> dict[str, list[str]]:
    """Every option of every subcommand whose choices include an engine: "command --option" -> its choices."""
    found = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for command, sub in action.choices.items():
                for option in sub._actions:
                    if option.choices and set(real) & set(option.choices):
                        found[f"{command} {option.option_strings[0]}"] = list(option.choices)
    return found


def _generators_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="graphdem")
    cli.add_commands(parser.add_subparsers(dest="command"))
    return parser


def test_a_registered_engine_is_offered_wherever_an_engine_is_chosen():
    """One line in generators/engines.py offers a new engine in every choice: the `graphdem` options, the
    cross-check's per-engine option, the config schema's enum (a scene's section may name it), every scene's
    engines and the workflow's engine list (tests/test_architecture.py checks that nothing else names one)."""
    real = engines.names()
    with registered(FAKE):
        parser = _generators_parser()
        options = _engine_options(parser, real)
        assert set(options) == {"prepare --engine", "restitution --engines", "transfer --trained-on",
                                "transfer --other-engine"}
        assert all(choices == [*real, FAKE] for choices in options.values())
        scene = scenes.names()[0]
        args = parser.parse_args(["crosscheck", "--scene", scene, f"--{real[0]}", "a.h5", f"--{FAKE}", "b.h5",
                                  "c.h5", "--out", "x.csv"])
        assert getattr(args, FAKE) == [Path("b.h5"), Path("c.h5")]
        assert config.schema()["$defs"]["dem_scene"]["properties"]["engine"]["enum"] == [*real, FAKE]
        assert config.load({"scale": "ci", scene: {"engine": FAKE}})[scene]["engine"] == FAKE
        assert all(FAKE in scenes.get(name).engines for name in scenes.names())
        assert _workflow_engines() == [*real, FAKE]
        with pytest.raises(ModuleNotFoundError, match=f"generators.{FAKE}"):    # its package is the rest of the work
            engines.driver(FAKE)
    assert engines.names() == real and _workflow_engines() == real                        # cleaned up after
    assert config.schema()["$defs"]["dem_scene"]["properties"]["engine"]["enum"] == real
    assert FAKE not in _engine_options(_generators_parser(), real)["prepare --engine"]


def _workflow_engines() -> list[str]:
    """The workflow's engine list (workflow/rules/common.smk's ENGINES), evaluated without Snakemake."""
    line, = [line for line in (ROOT / "workflow" / "rules" / "common.smk").read_text().splitlines()
             if line.startswith("ENGINES = ")]
    return eval(line.split("=", 1)[1].split("#", 1)[0], {"gengines": engines})   # noqa: S307 (our own file)


def test_every_driver_provides_what_the_registry_asks_for():
    """Each registered engine's driver: settle, record, read_raw, CONTACT_MODEL, PARALLEL, ERRORS (and
    ranks_problem where it takes MPI ranks); an engine taking ranks reports no problem at one rank."""
    for name in engines.NAMES:
        driver = engines.driver(name)
        assert all(callable(getattr(driver, f)) for f in ("settle", "run_recording", "read_raw")), name
        assert isinstance(driver.CONTACT_MODEL, str) and driver.PARALLEL in engines.PARALLEL_KINDS, name
        assert all(issubclass(e, Exception) for e in driver.ERRORS), name
        if engines.takes_ranks(name):
            assert driver.ranks_problem(1) is None
        assert engines.execution(name, 3) == ((3, 1) if engines.takes_ranks(name) else (1, 3))
    assert set(engines.errors()) <= set(cli.errors())
