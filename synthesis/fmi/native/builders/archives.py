"""ZIP archives written from members as they are compressed: FMUs and SSP files per law.

zipfile compresses every member it writes; the package writes many archives that differ from an
archive it already has in a member or two (a law FMU from the interpreter FMU, a closed-loop FMU
from its components, the same archive with a new model description).  Here the unchanged
members are copied as their compressed bytes, and only the new ones are deflated.

* :func:`raw_members` -- the members of an archive: ``(ZipInfo, compressed bytes)``;
* :func:`deflated`, :func:`stored`, :func:`copied` -- entries of a new archive;
* :func:`zip_archive` -- the archive's bytes; :func:`write_archive` writes them atomically.
"""
from __future__ import annotations

import copy
import os
import struct
import zipfile
import zlib
from functools import lru_cache
from pathlib import Path

__all__ = ["raw_members", "compressed_members", "compressed_file", "deflated", "stored", "copied", "zip_archive", "write_archive"]

# [choice] The archives are written here, not by zipfile: zipfile can only recompress a member
# it copies, and recompressing the same binaries and sources per law was most of an export's
# time (a closed-loop FMU of the tutorial's hopper: 2.4 s, of which 1.5 s in zlib).  Plain ZIP
# (PKWARE APPNOTE 4.3: local headers, central directory, end record; no ZIP64: FMUs of a few
# MB), read back by zipfile and fmpy in the tests.
_ZIP_TIME = (0, (1 << 5) | 1)          # 1980-01-01 00:00: the same bytes for the same content


def _raw_data(fh, info) -> bytes:
    """The compressed bytes of the member ``info`` of the open archive ``fh``."""
    fh.seek(info.header_offset)
    head = fh.read(30)
    if head[:4] != b"PK\x03\x04":
        raise zipfile.BadZipFile(f"no local header for {info.filename}")
    n, m = struct.unpack("<HH", head[26:30])
    fh.seek(info.header_offset + 30 + n + m)
    return fh.read(info.compress_size)


def raw_members(path) -> list:
    """``[(ZipInfo, compressed bytes)]`` of the archive ``path``, in its order.

    Raises
    ------
    zipfile.BadZipFile
        Not a ZIP archive, or one with a member this writer cannot copy (encrypted, ZIP64).
    """
    with open(path, "rb") as fh, zipfile.ZipFile(fh) as z:
        out = []
        for info in z.infolist():
            if info.flag_bits & 0x1 or info.file_size >= 0xFFFFFFFF:
                raise zipfile.BadZipFile(f"{path}: member {info.filename} is encrypted or ZIP64")
            if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
                raise zipfile.BadZipFile(f"{path}: member {info.filename} is neither stored "
                                         f"nor deflated")
            out.append((info, _raw_data(fh, info)))
        return out


def compressed_members(path) -> list:
    """:func:`raw_members` of ``path`` with its stored members deflated (level 6, zipfile's
    default), once per process and version of the file: the members of a component copied into
    many archives (a plant FMU whose builder stores its files)."""
    p = Path(path)
    st = p.stat()
    return _compressed_members(p.resolve(), st.st_size, st.st_mtime_ns)


@lru_cache(maxsize=8)
def _compressed_members(path: Path, size: int, stamp: int) -> list:
    out = []
    for info, data in raw_members(path):
        if info.compress_type == zipfile.ZIP_STORED and info.file_size:
            name, method, _, _, data = deflated(info.filename, data, level=6)
            info = copy.copy(info)
            info.compress_type = method
        out.append((info, data))
    return out


def compressed_file(name: str, path) -> tuple:
    """The file ``path`` as the member ``name``, deflated (level 6) once per process and version
    of the file: a component copied whole into many archives (an SSP file's plant FMU)."""
    p = Path(path)
    st = p.stat()
    _, method, crc, size, data = _compressed_file(p.resolve(), st.st_size, st.st_mtime_ns)
    return name, method, crc, size, data


@lru_cache(maxsize=8)
def _compressed_file(path: Path, size: int, stamp: int) -> tuple:
    return deflated(path.name, path.read_bytes(), level=6)


def deflated(name: str, data: bytes, level: int = 1) -> tuple:
    """A new member ``name`` with ``data`` deflated (level 1: a few times faster than zipfile's
    default level and about as small for the package's text and binaries)."""
    c = zlib.compressobj(level, zlib.DEFLATED, -15)
    return name, zipfile.ZIP_DEFLATED, zlib.crc32(data), len(data), c.compress(data) + c.flush()


def stored(name: str, data: bytes) -> tuple:
    """A new member ``name`` with ``data`` as it is (for data already compressed: FMUs)."""
    return name, zipfile.ZIP_STORED, zlib.crc32(data), len(data), data


def copied(name: str, info: zipfile.ZipInfo, data: bytes) -> tuple:
    """The member ``info`` of another archive with its compressed bytes ``data``, as ``name``."""
    return name, info.compress_type, info.CRC, info.file_size, data


def zip_archive(entries) -> bytes:
    """A ZIP archive of ``entries`` ``(name, method, crc32, size, compressed bytes)``."""
    body, central = bytearray(), bytearray()
    for name, method, crc, size, data in entries:
        raw, offset = name.encode(), len(body)
        fields = (method, *_ZIP_TIME, crc, len(data), size, len(raw))
        body += struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, *fields, 0) + raw + data
        central += struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, 0, *fields, 0, 0, 0,
                               0, 0, offset) + raw
    end = struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, len(entries), len(entries), len(central),
                      len(body), 0)
    return bytes(body + central + end)


def write_archive(dest, entries) -> Path:
    """Write the archive of ``entries`` to ``dest`` atomically (a ``.part`` file renamed)."""
    dest = Path(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    part = dest.with_name(dest.name + ".part")
    part.write_bytes(zip_archive(entries))
    os.replace(part, dest)
    return dest
