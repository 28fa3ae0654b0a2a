"""The seal: a checksum of an archive's structure, checked before HDF5 reads the file.

HDF5 trusts its own structure (superblock, object headers, heaps); some damage there
makes it loop forever inside C code, where no Python time-out can reach it. So a damaged
structure must never be handed to HDF5. The writer changes no byte of the structure of
a live archive, only the contents of fixed-size datasets in room made for them (see
:mod:`.format`); everything else is fixed from the moment the file is written. That
fixed part is checksummed when the file is written, and the checksum, with the list of
byte ranges it leaves out, kept in the file's userblock: the first ``USERBLOCK`` bytes,
which HDF5 reserves for the user and never reads. A reader checks the seal with plain
file reads first; only an intact structure goes to HDF5, and the contents left out are
checked part by part by their own checksums (:mod:`.reader`).

Archives written before the seal existed (format 1) have no userblock: their HDF5
signature sits at byte 0, and they are read as before.
"""

from __future__ import annotations

import os
import struct
import zlib

import h5py

USERBLOCK = 1 << 16  # bytes; a power of two >= 512, as HDF5 requires
MAGIC = b"RCOSIM\x02\x00"
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_HEAD = struct.Struct("<8sIIQI")  # magic, header crc, number of ranges, file length, structure crc
_RANGE = struct.Struct("<QQ")
MAX_RANGES = (USERBLOCK - _HEAD.size) // _RANGE.size
# Bytes 20-23 of a version 0 superblock are its consistency flags, which HDF5 sets while
# the file is open for writing (and does not act on): they are left out too.
_FLAGS = 20, 24


class Unsealed(Exception):
    """A file without a seal (an archive of format 1)."""


def live_ranges(path: str) -> list[tuple[int, int]]:
    """Byte ranges a live writer may change, and that the seal leaves out: the contents
    of the contiguous fixed-size datasets (a variable-length dataset's contents point
    into a heap, so they stay under the seal), plus the superblock's flags."""
    found = []

    def visit(name, obj):
        if isinstance(obj, h5py.Dataset) and obj.id.get_offset() is not None and not _variable_length(obj.dtype):
            found.append((obj.id.get_offset(), obj.id.get_offset() + obj.id.get_storage_size()))

    with h5py.File(path, "r", locking=False) as f:
        f.visititems(visit)
    return sorted([(USERBLOCK + _FLAGS[0], USERBLOCK + _FLAGS[1])] + found)


def _variable_length(dtype) -> bool:
    text = h5py.check_string_dtype(dtype)
    return h5py.check_vlen_dtype(dtype) is not None or (text is not None and text.length is None)


def seal(path: str) -> None:
    """Write the seal of a just-written archive (made with ``userblock_size=USERBLOCK``)."""
    ranges = live_ranges(path)
    if len(ranges) > MAX_RANGES:
        raise ValueError(f"{len(ranges)} datasets: more than the seal's {MAX_RANGES}")
    length = os.path.getsize(path)
    with open(path, "r+b") as fh:
        crc = _structure_crc(fh, length, ranges)
        body = struct.pack("<IQI", len(ranges), length, crc) + b"".join(_RANGE.pack(a, b) for a, b in ranges)
        fh.seek(0)
        fh.write(MAGIC + struct.pack("<I", zlib.crc32(body)) + body)


def check(path: str) -> str | None:
    """None when the seal holds; else what is wrong. :class:`Unsealed` for a file of
    format 1; ``OSError`` when the file cannot be read at all."""
    with open(path, "rb") as fh:
        head = fh.read(USERBLOCK)
        if head[:8] != MAGIC:
            if head[:8] == HDF5_SIGNATURE:
                raise Unsealed()
            return "its first bytes are neither a seal nor an HDF5 signature"
        magic, head_crc, n, length, crc = _HEAD.unpack_from(head)
        if n > MAX_RANGES:
            return "the seal is damaged"
        body = head[12:_HEAD.size + n * _RANGE.size]
        if zlib.crc32(body) != head_crc:
            return "the seal is damaged"
        ranges = [_RANGE.unpack_from(head, _HEAD.size + k * _RANGE.size) for k in range(n)]
        size = os.fstat(fh.fileno()).st_size
        if size != length:
            return f"the file has {size} bytes, it was written with {length}"
        if _structure_crc(fh, length, ranges) != crc:
            return "its structure fails its checksum"
    return None


def _structure_crc(fh, length: int, ranges) -> int:
    """CRC-32 of the file after the userblock, the ranges left out."""
    crc, pos = 0, USERBLOCK
    for start, end in sorted(ranges) + [(length, length)]:
        start, end = max(start, pos), min(max(end, start), length)
        if start > pos:
            fh.seek(pos)
            crc = zlib.crc32(fh.read(start - pos), crc)
        pos = max(pos, end)
    return crc
