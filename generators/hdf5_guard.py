"""Reading an HDF5 file at a bounded, local cost: every object reached only through links inside the file, every
dataset's decompressed size taken from a byte budget before it is read.

An HDF5 file can make a reader open other files (external links, virtual datasets, external raw storage: a FIFO
among them hangs it; a missing source reads as fill values) or allocate far more than it holds (a dataset that
declares a huge shape, a chunk larger than its dataset, a deflate stream that inflates past its chunk: HDF5's
filter grows its buffer until the stream ends). :func:`node`, :func:`dataset` and :func:`attribute` refuse all of
these by name (:class:`Refused`: the file, the object's path, what it is and what is allowed) before any data is
read; :class:`Budget` bounds what one file may make its reader allocate.
"""

from __future__ import annotations

import math
import zlib
from pathlib import Path

import h5py
import numpy as np

#: the filters a dataset may use (the writer's gzip + shuffle; fletcher32 checksums): each one's output size is
#: bounded by its chunk, the deflate stream's checked chunk by chunk before HDF5 inflates it
ALLOWED_FILTERS = {h5py.h5z.FILTER_DEFLATE: "gzip", h5py.h5z.FILTER_SHUFFLE: "shuffle",
                   h5py.h5z.FILTER_FLETCHER32: "fletcher32"}
#: soft links followed in a row before the path is refused as a loop (HDF5's own traversal limit)
MAX_SOFT_LINKS = 16
NUMERIC_KINDS = "biuf"


class Refused(ValueError):
    """An HDF5 object the reader will not touch; the message names the file, the object and why."""


class Budget:
    """The bytes a reader may still allocate for one file's data: ``limit`` in all, taken dataset by dataset (and
    attribute by attribute) before each is read."""

    def __init__(self, path: Path, limit: int):
        self.path, self.limit, self.used = path, int(limit), 0

    def take(self, what: str, nbytes: int) -> None:
        """Count ``nbytes`` for ``what``; refuse when the file's total would pass the limit."""
        if self.used + nbytes > self.limit:
            size = self.path.stat().st_size
            raise Refused(f"{self.path}: {what} would decompress to {nbytes / 2**20:,.1f} MiB, which with the "
                          f"{self.used / 2**20:,.1f} MiB read before passes the {self.limit / 2**20:,.0f} MiB a file "
                          f"of {size / 2**20:,.2f} MiB may hold; refused before reading")
        self.used += int(nbytes)


def _link_target(link: h5py.SoftLink, parent: str) -> str:
    return link.path if link.path.startswith("/") else f"{parent.rstrip('/')}/{link.path}"


def node(f: h5py.File, key: str, path: Path, _depth: int = 0) -> h5py.HLObject | None:
    """The object at ``key`` (None when absent), reached through hard links and through soft links followed here
    (each to a path inside the file, checked the same way); an external or user-defined link on the way, a
    dangling soft link or a loop of them is refused by name, before HDF5 opens anything."""
    current: h5py.HLObject = f["/"]
    walked = ""
    for name in (part for part in key.split("/") if part and part != "."):
        here = f"{walked}/{name}"
        if not isinstance(current, h5py.Group):
            raise Refused(f"{path}: {walked.lstrip('/')} must be a group (it holds {key}), found a "
                          f"{type(current).__name__}")
        try:
            link = current.get(name, getlink=True)
        except (TypeError, KeyError, OSError) as exc:
            raise Refused(f"{path}: {here.lstrip('/')} is a link of a kind this reader does not follow: {exc}") from exc
        if link is None:
            return None
        if isinstance(link, h5py.SoftLink):
            if _depth >= MAX_SOFT_LINKS:
                raise Refused(f"{path}: {here.lstrip('/')}: more than {MAX_SOFT_LINKS} soft links in a row (a loop?)")
            target = _link_target(link, walked or "/")
            current = node(f, target, path, _depth + 1)
            if current is None:
                raise Refused(f"{path}: {here.lstrip('/')} is a soft link to {link.path}, which does not exist")
        elif isinstance(link, h5py.HardLink):
            current = current[name]
        else:
            what = (f"an external link to {link.filename}:{link.path}" if isinstance(link, h5py.ExternalLink)
                    else f"a {type(link).__name__}")
            raise Refused(f"{path}: {here.lstrip('/')} is {what}; only objects inside the file are read (hard "
                          f"links, soft links within it)")
        walked = here
    return current


def _check_local(ds: h5py.Dataset, key: str, path: Path) -> None:
    """Refuse a dataset whose data lives outside the file: virtual, or with external raw storage."""
    if ds.is_virtual:
        sources = sorted({s.file_name for s in ds.virtual_sources()})
        raise Refused(f"{path}: {key} is a virtual dataset (its data is read from {', '.join(sources)}); only "
                      f"datasets stored in the file are read")
    if ds.external:
        files = sorted({str(name) for name, _, _ in ds.external})
        raise Refused(f"{path}: {key} stores its data in external files ({', '.join(files)}); only datasets "
                      f"stored in the file are read")


def dataset(f: h5py.File, key: str, path: Path, budget: Budget, kinds: str = NUMERIC_KINDS) -> h5py.Dataset | None:
    """The dataset at ``key`` (None when absent), checked before any of it is read: reached inside the file
    (:func:`node`), stored in it, of a dtype of ``kinds`` (numbers and booleans: no strings, references or
    compounds), its size and one chunk's taken from ``budget``, its filters allowed and every deflated chunk
    inflating to no more than its chunk."""
    obj = node(f, key, path)
    if obj is None:
        return None
    if not isinstance(obj, h5py.Dataset):
        raise Refused(f"{path}: {key} must be a dataset, found a {type(obj).__name__}")
    _check_local(obj, key, path)
    if obj.shape is None:
        raise Refused(f"{path}: {key} has no dataspace (an empty dataset); expected an array")
    if obj.dtype.kind not in kinds or obj.dtype.names or obj.dtype.subdtype:
        raise Refused(f"{path}: {key} must hold numbers or booleans, got dtype {obj.dtype}; refused before reading")
    budget.take(f"{key} (shape {obj.shape}, {obj.dtype})", math.prod(obj.shape) * obj.dtype.itemsize)
    if obj.chunks is not None:
        chunk = math.prod(obj.chunks) * obj.dtype.itemsize
        budget.take(f"one chunk of {key} (chunk shape {obj.chunks})", chunk)
        _check_filters(obj, key, path, chunk)
    return obj


def _check_filters(ds: h5py.Dataset, key: str, path: Path, chunk: int) -> None:
    """Refuse filters outside ALLOWED_FILTERS and deflated chunks that inflate past their chunk's bytes (plus a
    fletcher32 checksum), checked one chunk at a time from the raw bytes stored."""
    plist = ds.id.get_create_plist()
    codes = [plist.get_filter(i)[0] for i in range(plist.get_nfilters())]
    for code in codes:
        if code not in ALLOWED_FILTERS:
            raise Refused(f"{path}: {key} uses HDF5 filter {code}; allowed: "
                          f"{', '.join(f'{n} ({c})' for c, n in ALLOWED_FILTERS.items())}")
    deflate = codes.count(h5py.h5z.FILTER_DEFLATE)
    if deflate > 1:
        raise Refused(f"{path}: {key} is deflated {deflate} times; a dataset is compressed once")
    if not deflate:
        return
    most = chunk + 4 * codes.count(h5py.h5z.FILTER_FLETCHER32)
    skip_bit = 1 << codes.index(h5py.h5z.FILTER_DEFLATE)
    size = path.stat().st_size

    def check(info) -> None:
        if info.size > size:
            raise Refused(f"{path}: {key}: the chunk at {info.chunk_offset} claims {info.size} bytes, more than the "
                          f"file holds")
        if info.filter_mask & skip_bit:
            return
        raw = ds.id.read_direct_chunk(info.chunk_offset)[1]
        stream = zlib.decompressobj()
        try:
            out = len(stream.decompress(raw, most + 1))
        except zlib.error as exc:
            raise Refused(f"{path}: {key}: the chunk at {info.chunk_offset} is not a valid deflate stream "
                          f"({exc})") from exc
        if out > most:
            raise Refused(f"{path}: {key}: the chunk at {info.chunk_offset} inflates past its {chunk} bytes (a "
                          f"compression bomb); refused before reading")

    ds.id.chunk_iter(check)


def attribute(obj: h5py.HLObject, name: str, where: str, path: Path, budget: Budget, default=None):
    """The attribute ``name`` of ``obj`` (at ``where``; ``default`` when absent), its size taken from ``budget``
    before it is read: an array of fixed-size values its bytes, an array of variable-length ones as if each held
    the whole file, a scalar (one variable-length value at most the file) by what it turns out to hold."""
    if name not in obj.attrs:
        return default
    aid = obj.attrs.get_id(name)
    shape = aid.shape
    dtype = aid.dtype
    if shape:
        each = path.stat().st_size if dtype.hasobject else dtype.itemsize     # variable-length: a heap object each
        budget.take(f"attribute {name} of {where} (shape {shape}, {dtype})", math.prod(shape) * each)
    value = obj.attrs[name]
    if not shape:
        held = len(value) if isinstance(value, str | bytes) else np.asarray(value).nbytes
        budget.take(f"attribute {name} of {where}", held)
    return value
