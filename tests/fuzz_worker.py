"""Runs a reader over fuzzed files in a child process with bounded memory, for the readers' fuzz tests.

``python -m tests.fuzz_worker CASES.json``: CASES.json holds ``{"warmup": case, "cases": [case, ...]}``, each case
``{"name": ..., "reader": "h5md" | "checkpoint" | "cli", "path": ..., "argv": [...] (cli)}``. After the imports and
the warm-up case, the data segment is capped at what it holds plus ALLOWED_GROWTH (RLIMIT_DATA: a reader that tries
to allocate more fails instead of taking the machine's memory), and each case prints one JSON line as it starts and
one with its outcome: ``ok`` (a valid read, or exit status 0), ``refused`` (the reader's named error, or exit status
1: its message) or ``escaped`` (any other exception: its type and message). The last line gives the peak resident
growth over the warm baseline (``ru_maxrss``). A case that hangs leaves its start line last, for the caller's
timeout to name.
"""

from __future__ import annotations

import contextlib
import io
import json
import resource
import sys

ALLOWED_GROWTH = 512 * 2**20


def _data_bytes() -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmData:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmData in /proc/self/status")


def _run(case: dict) -> tuple[str, str]:
    from generators import h5md
    from graphdem import cli
    from surrogate import checkpoint

    try:
        if case["reader"] == "h5md":
            h5md.read(case["path"])
            return "ok", ""
        if case["reader"] == "checkpoint":
            checkpoint.simulator_from(case["path"], "cpu")
            return "ok", ""
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                code = cli.main(case["argv"])
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else 1
        return ("ok" if code == 0 else "refused" if code == 1 else f"exit {code}"), err.getvalue()
    except (h5md.H5MDError, checkpoint.CheckpointError) as exc:
        return "refused", str(exc)
    except BaseException as exc:  # noqa: BLE001 - whatever escapes is what the test reports
        return "escaped", f"{type(exc).__name__}: {exc}"


def main(cases_file: str) -> None:
    spec = json.loads(open(cases_file).read())
    outcome = _run(spec["warmup"])
    if outcome[0] != "ok":
        raise SystemExit(f"the warm-up case failed: {outcome}")
    limit = _data_bytes() + ALLOWED_GROWTH
    resource.setrlimit(resource.RLIMIT_DATA, (limit, resource.getrlimit(resource.RLIMIT_DATA)[1]))
    baseline = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    for case in spec["cases"]:
        print(json.dumps({"start": case["name"]}), flush=True)
        status, message = _run(case)
        print(json.dumps({"name": case["name"], "status": status, "message": message}), flush=True)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(json.dumps({"peak_growth": peak - baseline}), flush=True)


if __name__ == "__main__":
    main(sys.argv[1])


def run(cases: list[dict], warmup: dict, folder, timeout: float) -> tuple[dict[str, tuple[str, str]], int]:
    """Run ``cases`` in a child worker (from the test process): each case's (status, message) by name and the
    peak resident growth in bytes; a child that does not finish within ``timeout`` s fails the test, naming the
    case it hung on."""
    import subprocess
    from pathlib import Path

    import pytest

    spec = Path(folder) / "cases.json"
    spec.write_text(json.dumps({"warmup": warmup, "cases": cases}))
    try:
        done = subprocess.run([sys.executable, "-m", "tests.fuzz_worker", str(spec)], capture_output=True, text=True,
                              timeout=timeout, cwd=Path(__file__).resolve().parents[1])
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout.decode() if isinstance(exc.stdout, bytes) else exc.stdout or ""
        started = [json.loads(line)["start"] for line in out.splitlines() if line.startswith('{"start"')]
        pytest.fail(f"the reader hung on {started[-1] if started else 'its warm-up'} (no answer in {timeout} s)")
    lines = [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
    if done.returncode != 0 or not lines or "peak_growth" not in lines[-1]:
        pytest.fail(f"the worker died (status {done.returncode}) after {lines[-1:]}: {done.stderr[-2000:]}")
    return {r["name"]: (r["status"], r["message"]) for r in lines if "status" in r}, lines[-1]["peak_growth"]
