import h5py
import numpy as np
import pytest

from generators import h5md


def make_traj(t=5, n=4, d=2) -> h5md.Trajectory:
    rng = np.random.default_rng(0)
    return h5md.Trajectory(
        position=rng.uniform(0, 10, (t, n, d)).astype(np.float32),
        time=np.arange(t) * 0.1, step=np.arange(t) * 100,
        species=np.array([0, 1, 1, 2][:n]), radius=np.full(n, 0.5), mass=np.full(n, 2.0),
        kinematic=np.array([True, False, False, False][:n]),
        box_lower=np.zeros(d), box_upper=np.full(d, 10.0),
        parameters={"young": 1e9, "engine": "lammps", "profile": [[0, 1], [2, 3]], "dt": None},
        observables={"kinetic_energy": np.linspace(0, 1, t)}, observable_units={"kinetic_energy": "J"},
    )


def test_round_trip_keeps_every_field(tmp_path):
    traj = make_traj()
    path = h5md.write(tmp_path / "sim.h5", traj)
    back = h5md.read(path)
    np.testing.assert_array_equal(back.position, traj.position)
    np.testing.assert_array_equal(back.time, traj.time)
    np.testing.assert_array_equal(back.kinematic, traj.kinematic)
    np.testing.assert_array_equal(back.species, traj.species)
    assert back.parameters == traj.parameters
    np.testing.assert_allclose(back.observables["kinetic_energy"], traj.observables["kinetic_energy"])
    assert list(tmp_path.iterdir()) == [path]      # no temporary left behind


def test_file_follows_h5md_layout(tmp_path):
    path = h5md.write(tmp_path / "sim.h5", make_traj(d=3))
    with h5py.File(path) as f:
        assert list(f["h5md"].attrs["version"]) == [1, 1]
        assert f["h5md/creator"].attrs["name"] == "graphdem"
        assert f["particles/all/box"].attrs["dimension"] == 3
        assert f["particles/all/position/value"].shape == (5, 4, 3)
        assert f["particles/all/position/value"].dtype == np.float32
        assert f["particles/all/position/value"].chunks == (1, 4, 3)
        assert f["particles/all/kinematic"].dtype == bool


@pytest.mark.parametrize("mutate, message", [
    (lambda t: t.position.__setitem__((2, 1, 0), np.nan), "non-finite position at frame 2, particle 1"),
    (lambda t: setattr(t, "time", np.array([0, 0.1, 0.1, 0.3, 0.4])), "not strictly increasing"),
    (lambda t: setattr(t, "kinematic", None), "kinematic is missing"),
    (lambda t: setattr(t, "radius", np.ones(3)), "radius has shape"),
    (lambda t: setattr(t, "position", np.zeros((5, 4, 4))), "D in \\(2, 3\\)"),
])
def test_invalid_trajectory_is_not_written(tmp_path, mutate, message):
    traj = make_traj()
    mutate(traj)
    with pytest.raises(h5md.H5MDError, match=message):
        h5md.write(tmp_path / "bad.h5", traj)
    assert list(tmp_path.iterdir()) == []


def test_truncated_file_gives_clear_error(tmp_path):
    path = h5md.write(tmp_path / "sim.h5", make_traj())
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(h5md.H5MDError, match=f"{path}.*(corrupt|truncated)"):
        h5md.read(path)


def test_garbage_and_missing_files(tmp_path):
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"not hdf5 at all")
    with pytest.raises(h5md.H5MDError, match="junk.h5: not a readable HDF5 file"):
        h5md.read(junk)
    with pytest.raises(h5md.H5MDError, match="no such file"):
        h5md.read(tmp_path / "absent.h5")


def test_file_missing_a_dataset_names_it(tmp_path):
    path = h5md.write(tmp_path / "sim.h5", make_traj())
    with h5py.File(path, "a") as f:
        del f["particles/all/kinematic"]
    with pytest.raises(h5md.H5MDError, match="missing particles/all/kinematic"):
        h5md.read(path)


def test_corrupted_values_are_caught_on_read(tmp_path):
    path = h5md.write(tmp_path / "sim.h5", make_traj())
    with h5py.File(path, "a") as f:
        f["particles/all/position/value"][3, 2, 1] = np.inf
    with pytest.raises(h5md.H5MDError, match="non-finite position at frame 3, particle 2"):
        h5md.read(path)


def make_box_traj(d: int = 3) -> h5md.Trajectory:
    """A trajectory whose box does not start at the origin, with properties and a periodic axis."""
    traj = make_traj(d=d)
    traj.box_lower, traj.box_upper = np.array([-1.5, 0.25, 2.0][:d]), np.array([10.0, 11.0, 12.5][:d])
    traj.boundary = ("periodic",) + ("none",) * (d - 1)
    traj.properties, traj.property_names = np.arange(8, dtype=np.float32).reshape(4, 2), ("young", "poisson")
    return traj


def _elements(group: h5py.Group, prefix: str = "") -> dict[str, h5py.HLObject]:
    """Every object below ``group`` by path, hard links included (h5py's visititems names a linked object once)."""
    found = {}
    for name, node in group.items():
        found[prefix + name] = node
        if isinstance(node, h5py.Group):
            found.update(_elements(node, f"{prefix}{name}/"))
    return found


def _is_vlen_ascii(node: h5py.HLObject, attr: str) -> bool:
    kind = node.attrs.get_id(attr).get_type()
    return kind.is_variable_str() and kind.get_cset() == h5py.h5t.CSET_ASCII and node.attrs.get_id(attr).shape == ()


@pytest.mark.parametrize("d", [2, 3])
def test_units_are_declared_by_the_units_module_and_are_si(tmp_path, d):
    path = h5md.write(tmp_path / "sim.h5", make_box_traj(d))
    with h5py.File(path) as f:
        units = {name: node.attrs["unit"] for name, node in _elements(f).items() if "unit" in node.attrs}
        module = f["h5md/modules/units"]
        assert list(module.attrs["version"]) == [1, 0] and module.attrs["version"].dtype.kind == "i"
        assert module.attrs["system"] == "SI" and _is_vlen_ascii(module, "system")
        assert all(_is_vlen_ascii(_elements(f)[name], "unit") for name in units)
    assert units == {
        "particles/all/position/value": "m", "particles/all/position/time": "s",
        "particles/all/box/edges/value": "m", "particles/all/box/edges/time": "s", "particles/all/box/lower": "m",
        "particles/all/radius": "m", "particles/all/mass": "kg", "observables/kinetic_energy/time": "s",
        "observables/kinetic_energy/value": "J",
    }


@pytest.mark.parametrize("units, shown", [({}, "None"), ({"kinetic_energy": ""}, "''"),
                                           ({"kinetic_energy": "µJ"}, "'µJ'")])
def test_an_observable_without_an_si_unit_is_not_written(tmp_path, units, shown):
    """Every observable's value carries its unit: one without (or with one the units module cannot hold as ASCII)
    is refused by name, and nothing is written."""
    traj = make_traj()
    traj.observable_units = units
    with pytest.raises(h5md.H5MDError, match=rf"sim.h5: observable 'kinetic_energy' has no unit \(observable_units"
                                             rf"\['kinetic_energy'\] = {shown}\)"):
        h5md.write(tmp_path / "sim.h5", traj)
    assert list(tmp_path.iterdir()) == []


def test_every_observable_reads_back_with_its_unit(tmp_path):
    traj = make_traj()
    traj.observables["shear_force"] = np.arange(5.0)
    traj.observable_units = {"kinetic_energy": "J", "shear_force": "N", "unused": "Pa"}   # a unit of none: not written
    back = h5md.read(h5md.write(tmp_path / "sim.h5", traj))
    assert back.observable_units == {"kinetic_energy": "J", "shear_force": "N"}
    with h5py.File(tmp_path / "sim.h5") as f:
        assert f["observables/shear_force/value"].attrs["unit"] == "N"
        assert _is_vlen_ascii(f["observables/shear_force/value"], "unit")
        assert "unit" not in f["observables/shear_force"].attrs      # on the value, as on position's


@pytest.mark.parametrize("d", [2, 3])
def test_time_dependent_elements_have_step_time_and_value_of_one_length(tmp_path, d):
    traj = make_box_traj(d)
    path = h5md.write(tmp_path / "sim.h5", traj)
    with h5py.File(path) as f:
        elements = {name: node for name, node in _elements(f).items()
                    if isinstance(node, h5py.Group) and "value" in node}
        assert set(elements) == {"particles/all/position", "particles/all/box/edges", "observables/kinetic_energy"}
        position = f["particles/all/position"]
        for name, element in elements.items():
            step, time, value = element["step"], element["time"], element["value"]
            assert step.dtype.kind == "i" and time.dtype.kind == "f", name
            assert step.shape == time.shape == value.shape[:1] == (traj.n_frames,), name
            np.testing.assert_array_equal(step[()], traj.step)
            np.testing.assert_array_equal(time[()], traj.time)
            assert step.id == position["step"].id and time.id == position["time"].id, name   # hard links


@pytest.mark.parametrize("d", [2, 3])
def test_box_has_dimension_boundary_and_edges_per_frame(tmp_path, d):
    traj = make_box_traj(d)
    path = h5md.write(tmp_path / "sim.h5", traj)
    with h5py.File(path) as f:
        box = f["particles/all/box"]
        dimension = box.attrs["dimension"]
        assert dimension == d and dimension.shape == () and dimension.dtype.kind == "i"
        assert box.attrs["boundary"].dtype.kind == "S" and box.attrs["boundary"].shape == (d,)
        assert [b.decode() for b in box.attrs["boundary"]] == ["periodic"] + ["none"] * (d - 1)
        np.testing.assert_array_equal(box["edges/value"][()], np.tile(traj.box_upper - traj.box_lower, (5, 1)))
        np.testing.assert_array_equal(box["lower"][()], traj.box_lower)


@pytest.mark.parametrize("d", [2, 3])
def test_new_layout_round_trip_keeps_every_number(tmp_path, d):
    traj = make_box_traj(d)
    back = h5md.read(h5md.write(tmp_path / "sim.h5", traj))
    for name in ("position", "time", "step", "species", "radius", "mass", "kinematic", "box_lower", "box_upper",
                 "properties"):
        np.testing.assert_array_equal(getattr(back, name), getattr(traj, name), err_msg=name)
    assert back.boundary == traj.boundary and back.property_names == traj.property_names
    assert back.parameters == traj.parameters
    np.testing.assert_array_equal(back.observables["kinetic_energy"], traj.observables["kinetic_energy"])
    assert back.observable_units == {"kinetic_energy": "J"}
    part = h5md.read(tmp_path / "sim.h5", frames=slice(1, 4))
    np.testing.assert_array_equal(part.position, traj.position[1:4])
    np.testing.assert_array_equal(part.box_upper, traj.box_upper)


def write_old_layout(path, traj: h5md.Trajectory, lower: bool = True) -> None:
    """A file as the writer made it before the units module: ``box/edges`` a fixed dataset [D] with ``box/lower``
    beside it (left out with ``lower=False``, as another writer may), units without a declared module, copied
    step/time in observables."""
    with h5py.File(path, "w") as f:
        f.create_group("h5md").attrs["version"] = np.array([1, 1], np.int32)
        f.create_group("h5md/author").attrs["name"] = "graphdem"
        box = f.create_group("particles/all/box")
        box.attrs["dimension"] = np.int32(traj.dim)
        box.attrs["boundary"] = np.array(traj.boundary, dtype="S8")
        box["edges"] = traj.box_upper - traj.box_lower
        if lower:
            box["lower"] = traj.box_lower
        pos = f.create_group("particles/all/position")
        pos.create_dataset("value", data=traj.position.astype(np.float32), chunks=(1, *traj.position.shape[1:]))
        pos["step"], pos["time"] = traj.step.astype(np.int64), traj.time
        pos["time"].attrs["unit"], pos["value"].attrs["unit"] = "s", "m"
        for name, dtype in (("species", np.int32), ("radius", np.float32), ("mass", np.float32), ("kinematic", bool)):
            f[f"particles/all/{name}"] = np.asarray(getattr(traj, name), dtype)
        f.create_group("parameters").attrs["engine"] = "lammps"
        for name, values in traj.observables.items():
            f[f"observables/{name}/value"], f[f"observables/{name}/step"] = values, traj.step
            f[f"observables/{name}/time"] = traj.time


@pytest.mark.parametrize("d", [2, 3])
def test_files_of_the_old_layout_still_read(tmp_path, d):
    traj = make_box_traj(d)
    traj.properties, traj.property_names = None, ()
    write_old_layout(tmp_path / "old.h5", traj)
    back = h5md.read(tmp_path / "old.h5")
    for name in ("position", "time", "step", "species", "radius", "mass", "kinematic", "box_lower", "box_upper"):
        np.testing.assert_array_equal(getattr(back, name), getattr(traj, name), err_msg=name)
    assert back.boundary == traj.boundary and back.parameters == {"engine": "lammps"}
    np.testing.assert_array_equal(back.observables["kinetic_energy"], traj.observables["kinetic_energy"])
    assert back.observable_units == {}                  # written without one: none is made up
    write_old_layout(tmp_path / "older.h5", traj, lower=False)
    older = h5md.read(tmp_path / "older.h5")
    np.testing.assert_array_equal(older.box_lower, np.zeros(d))
    np.testing.assert_array_equal(older.box_upper, traj.box_upper - traj.box_lower)


@pytest.mark.parametrize("edit, message", [
    (lambda f: f["particles/all/box/edges/value"].__setitem__(2, [9.0, 9.0, 9.0]), "changes over time"),
    (lambda f: f.__delitem__("particles/all/box/edges/value"), "missing particles/all/box/edges/value"),
])
def test_a_box_that_is_not_one_fixed_box_is_refused(tmp_path, edit, message):
    path = h5md.write(tmp_path / "sim.h5", make_box_traj(3))
    with h5py.File(path, "a") as f:
        edit(f)
    with pytest.raises(h5md.H5MDError, match=message):
        h5md.read(path)


@pytest.mark.parametrize("edit, message", [
    (lambda f: f["particles/all/box/edges/value"].__setitem__(Ellipsis, [np.inf, 10.0, 10.0]),
     "edges/value must hold finite positive box edges"),
    (lambda f: f["particles/all/box/edges/value"].__setitem__(Ellipsis, [0.0, 10.0, 10.0]),
     "edges/value must hold finite positive box edges"),
    (lambda f: f["particles/all/box/lower"].__setitem__(1, np.nan), "box/lower must hold a finite corner"),
    (lambda f: f["particles/all/radius"].__setitem__(0, np.inf), "non-finite values in radius"),
])
def test_non_finite_or_empty_boxes_and_geometry_are_refused_by_name(tmp_path, edit, message):
    path = h5md.write(tmp_path / "sim.h5", make_box_traj(3))
    with h5py.File(path, "a") as f:
        edit(f)
    with pytest.raises(h5md.H5MDError, match=f"{path}: .*{message}"):
        h5md.read(path)


def test_a_box_with_non_finite_corners_is_not_written(tmp_path):
    traj = make_box_traj(2)
    traj.box_upper = np.array([np.inf, 5.0])
    with pytest.raises(h5md.H5MDError, match="non-finite values in box_upper"):
        h5md.write(tmp_path / "sim.h5", traj)
    assert list(tmp_path.iterdir()) == []


def test_links_out_of_the_file_are_refused_and_links_inside_it_read(tmp_path):
    import os
    os.mkfifo(tmp_path / "fifo")
    path = h5md.write(tmp_path / "sim.h5", make_traj())
    with h5py.File(path, "a") as f:
        f.move("particles/all/radius", "/kept_radius")
        f["particles/all/radius"] = h5py.SoftLink("/kept_radius")
    np.testing.assert_array_equal(h5md.read(path).radius, make_traj().radius)
    with h5py.File(path, "a") as f:
        del f["particles/all/mass"]
        f["particles/all/mass"] = h5py.ExternalLink(str(tmp_path / "fifo"), "/mass")
    with pytest.raises(h5md.H5MDError, match=f"{path}: particles/all/mass is an external link to .*fifo:/mass"):
        h5md.read(path)


def test_a_file_may_make_its_reader_allocate_its_budget_in_all_not_per_dataset(tmp_path):
    path = h5md.write(tmp_path / "sim.h5", make_traj())
    limit = max(h5md.MIN_DECLARED_BYTES, h5md.DECLARED_PER_FILE_BYTE * path.stat().st_size)
    with h5py.File(path, "a") as f:
        for key in ("observables/a/value", "observables/b/value"):
            f.create_dataset(key, shape=(5,), dtype="f8")
        del f["particles/all/radius"]
        f.create_dataset("particles/all/radius", shape=(limit // 4 - 100,), dtype="f4", chunks=(2**16,),
                         compression="gzip")                                     # within the limit alone
        f.create_dataset("particles/all/properties", shape=(4, 100), dtype="f4")
    with pytest.raises(h5md.H5MDError, match="passes the 256 MiB a file of"):
        h5md.read(path)
