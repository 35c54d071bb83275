import os
import zlib

import h5py
import numpy as np
import pytest

from generators import hdf5_guard


@pytest.fixture
def sample(tmp_path):
    """A file with a dataset, a group and a FIFO beside it."""
    path = tmp_path / "sample.h5"
    os.mkfifo(tmp_path / "fifo")
    with h5py.File(path, "w") as f:
        f.create_dataset("group/data", data=np.arange(12.0).reshape(3, 4), chunks=(1, 4), compression="gzip")
    return path


def budget(path, limit=2**20):
    return hdf5_guard.Budget(path, limit)


def test_a_dataset_inside_the_file_is_read_with_its_bytes_taken_from_the_budget(sample):
    spent = budget(sample)
    with h5py.File(sample) as f:
        data = hdf5_guard.dataset(f, "group/data", sample, spent)
        np.testing.assert_array_equal(data[()], np.arange(12.0).reshape(3, 4))
        assert spent.used == 12 * 8 + 4 * 8          # the dataset and one chunk
        assert hdf5_guard.dataset(f, "group/absent", sample, spent) is None


def test_a_soft_link_inside_the_file_is_followed(sample):
    with h5py.File(sample, "a") as f:
        f["alias"] = h5py.SoftLink("/group")
        f["group/relative"] = h5py.SoftLink("data")
    with h5py.File(sample) as f:
        assert hdf5_guard.dataset(f, "alias/data", sample, budget(sample)).shape == (3, 4)
        assert hdf5_guard.dataset(f, "group/relative", sample, budget(sample)).shape == (3, 4)


@pytest.mark.parametrize("make, message", [
    (lambda f, d: f.__setitem__("link", h5py.ExternalLink(str(d / "fifo"), "/x")), "link is an external link to"),
    (lambda f, d: f.__setitem__("link", h5py.SoftLink("/nowhere")), "link is a soft link to /nowhere, which does not"),
    (lambda f, d: f.__setitem__("link", h5py.SoftLink("/link")), "link: more than 16 soft links in a row"),
])
def test_links_that_leave_the_file_dangle_or_loop_are_refused_by_name(sample, make, message):
    with h5py.File(sample, "a") as f:
        make(f, sample.parent)
    with h5py.File(sample) as f, pytest.raises(hdf5_guard.Refused, match=f"{sample}: {message}"):
        hdf5_guard.node(f, "link/data", sample)


def test_virtual_datasets_and_external_storage_are_refused_before_reading(sample):
    fifo = str(sample.parent / "fifo")
    with h5py.File(sample, "a") as f:
        layout = h5py.VirtualLayout(shape=(3,), dtype="f8")
        layout[:] = h5py.VirtualSource(str(sample.parent / "absent.h5"), "x", shape=(3,))
        f.create_virtual_dataset("virtual", layout, fillvalue=0)
        f.create_dataset("external", shape=(3,), dtype="f8", external=[(fifo, 0, 24)])
    with h5py.File(sample) as f:
        with pytest.raises(hdf5_guard.Refused, match="virtual is a virtual dataset .*absent.h5"):
            hdf5_guard.dataset(f, "virtual", sample, budget(sample))
        with pytest.raises(hdf5_guard.Refused, match="external stores its data in external files .*fifo"):
            hdf5_guard.dataset(f, "external", sample, budget(sample))


def test_sizes_are_bounded_before_reading_declared_chunked_and_inflated(sample):
    with h5py.File(sample, "a") as f:
        f.create_dataset("declared", shape=(2**20,), dtype="f8")              # 8 MiB, nothing stored
        f.create_dataset("wide_chunk", shape=(4,), maxshape=(None,), chunks=(2**20,), dtype="f8")
        f["group/data"].id.write_direct_chunk((1, 0), zlib.compress(bytes(2**20)))   # 32 bytes inflating to 1 MiB
        f.create_dataset("text", data=np.array([b"a", b"b"]))
    with h5py.File(sample) as f:
        with pytest.raises(hdf5_guard.Refused, match=r"declared \(shape \(1048576,\), float64\) would decompress"):
            hdf5_guard.dataset(f, "declared", sample, budget(sample))
        with pytest.raises(hdf5_guard.Refused, match=r"one chunk of wide_chunk"):
            hdf5_guard.dataset(f, "wide_chunk", sample, budget(sample))
        with pytest.raises(hdf5_guard.Refused, match=r"chunk at \(1, 0\) inflates past its 32 bytes"):
            hdf5_guard.dataset(f, "group/data", sample, budget(sample))
        with pytest.raises(hdf5_guard.Refused, match="text must hold numbers or booleans, got dtype"):
            hdf5_guard.dataset(f, "text", sample, budget(sample))


def test_the_budget_counts_every_dataset_and_attribute_of_a_file(sample):
    with h5py.File(sample, "a") as f:
        f.attrs["names"] = np.array(["a", "b", "c"], dtype=h5py.string_dtype())
        f.attrs["note"] = "x" * 100
    spent = budget(sample, limit=sample.stat().st_size * 3 + 100)
    with h5py.File(sample) as f:
        assert list(hdf5_guard.attribute(f, "names", "/", sample, spent)) == ["a", "b", "c"]
        assert spent.used == 3 * sample.stat().st_size                # each variable-length value as the whole file
        assert hdf5_guard.attribute(f, "note", "/", sample, spent) == "x" * 100
        assert hdf5_guard.attribute(f, "absent", "/", sample, spent, "default") == "default"
        with pytest.raises(hdf5_guard.Refused, match="group/data .* passes the 0 MiB"):
            hdf5_guard.dataset(f, "group/data", sample, spent)
