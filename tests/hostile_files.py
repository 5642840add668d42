"""Hostile variants of valid point-cloud files (issue 27): each function takes the bytes of a
valid file written by lidarsim and returns a malformed one, the defect its name says."""

from __future__ import annotations

import io
import json
import re
import struct
import zipfile

import numpy as np


def _header_split(data: bytes, end: bytes) -> tuple[bytes, bytes]:
    cut = data.index(end) + len(end)
    return data[:cut], data[cut:]


def ply_sub(data: bytes, pattern: bytes, repl: bytes) -> bytes:
    head, body = _header_split(data, b"end_header\n")
    return re.sub(pattern, repl, head, count=1) + body


def pcd_sub(data: bytes, pattern: bytes, repl: bytes) -> bytes:
    head, body = _header_split(data, b"DATA binary\n")
    return re.sub(pattern, repl, head, count=1) + body


def ply_cases(valid: bytes) -> dict[str, tuple[bytes, str]]:
    """Name → (bytes, fragment the error must hold)."""
    count = rb"element vertex \d+"
    return {
        "huge count": (ply_sub(valid, count, b"element vertex 1099511627776"),
                       "1,099,511,627,776 vertices"),
        "negative count": (ply_sub(valid, count, b"element vertex -5"), "'-5'"),
        "non-integer count": (ply_sub(valid, count, b"element vertex 3.5"), "'3.5'"),
        "element without count": (ply_sub(valid, count, b"element vertex"),
                                  "not 'element NAME COUNT'"),
        "duplicate property": (ply_sub(valid, rb"(property double x\n)", rb"\1\1"),
                               "declared twice"),
        "truncated record": (valid[:-7], "file holds only"),
        "comment not JSON": (ply_sub(valid, rb"comment lidarsim-frame \{",
                                     b"comment lidarsim-frame {{{"), "not JSON"),
    }


def pcd_cases(valid: bytes) -> dict[str, tuple[bytes, str]]:
    return {
        "huge count": (pcd_sub(valid, rb"POINTS \d+", b"POINTS 1099511627776"),
                       "1,099,511,627,776 points"),
        "negative count": (pcd_sub(valid, rb"POINTS \d+", b"POINTS -3"), "'-3'"),
        "missing FIELDS": (pcd_sub(valid, rb"FIELDS [^\n]*\n", b""), "no FIELDS line"),
        "unknown TYPE": (pcd_sub(valid, rb"TYPE F", b"TYPE Q"), "TYPE Q"),
        "truncated record": (valid[:-3], "file holds only"),
    }


def las_cases(valid: bytes) -> dict[str, tuple[bytes, str]]:
    """LAS 1.4: legacy count at byte 107 (u32), 64-bit count at 247 (u64)."""
    huge = bytearray(valid)
    struct.pack_into("<I", huge, 107, 0)
    struct.pack_into("<Q", huge, 247, 2 ** 40)
    vlrs = bytearray(valid)
    vlrs[103] = 1  # the top byte of the VLR count: 16.7 million VLRs laspy would loop over
    out = {"huge count": (bytes(huge), "1,099,511,627,776 points"),
           "VLR count flipped": (bytes(vlrs), "16,777,2"),
           "truncated": (valid[:len(valid) // 2], "")}
    start = valid.find(b"lidarsim\0")
    if start >= 0:  # the metadata VLR: user id at +2 of its header; its data after 54 bytes
        data_at = start - 2 + 54
        bad = bytearray(valid)
        bad[data_at] = 0xFF
        out["metadata VLR not UTF-8"] = (bytes(bad), "not UTF-8 JSON")
        bad = bytearray(valid)
        bad[data_at] = ord("#")
        out["metadata VLR not JSON"] = (bytes(bad), "not UTF-8 JSON")
    return out


def npz_replace(valid: bytes, members: dict[str, bytes | None], *,
                compression: int = zipfile.ZIP_DEFLATED) -> bytes:
    """The archive with ``members`` replaced (``None`` removes one)."""
    out = io.BytesIO()
    with zipfile.ZipFile(io.BytesIO(valid)) as src, \
            zipfile.ZipFile(out, "w", compression=compression) as dst:
        for info in src.infolist():
            if info.filename in members:
                continue
            dst.writestr(info.filename, src.read(info))
        for name, data in members.items():
            if data is not None:
                dst.writestr(name, data)
    return out.getvalue()


def npy(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.lib.format.write_array(buffer, array, allow_pickle=True)
    return buffer.getvalue()


def npz_cases(valid: bytes) -> dict[str, tuple[bytes, str]]:
    with zipfile.ZipFile(io.BytesIO(valid)) as src:
        n = len(np.load(io.BytesIO(src.read("x.npy"))))
    # a bomb: 5 GB of zeros declared in the directory (deflate of zeros is ~1000:1; the
    # directory's size is what is checked, so the member is written with a small real size
    # and its declared size patched)
    bomb = io.BytesIO()
    with zipfile.ZipFile(bomb, "w", compression=zipfile.ZIP_DEFLATED) as dst:
        dst.writestr("x.npy", b"\0" * 1000)
        dst.writestr("y.npy", b"\0" * 1000)
    raw = bytearray(bomb.getvalue())
    for marker, at in ((b"PK\x01\x02", 24), (b"PK\x03\x04", 22)):  # central, local headers
        start = raw.find(marker)
        while start >= 0:  # each member declares ~2.4 GB inflated: 4.8 GB in all
            struct.pack_into("<I", raw, start + at, 2_400_000_000)
            start = raw.find(marker, start + 4)
    header = npy(np.zeros(1, dtype="f8"))
    shape_header = header.replace(b"(1,)", b"(68719476736,)")  # 2**36 rows
    return {
        "zip bomb": (bytes(raw), "inflates to"),
        "truncated zip": (valid[: len(valid) // 2], "cannot read NPZ"),
        "columns of different lengths": (npz_replace(valid, {"y.npy": npy(np.zeros(n + 1))}),
                                         "values where the others have"),
        "text column": (npz_replace(valid, {"y.npy": npy(np.array(["a"] * n))}),
                        "not a number type"),
        "2-D column": (npz_replace(valid, {"x.npy": npy(np.zeros((n, 2)))}),
                       "not one value per point"),
        "pickle": (npz_replace(valid, {"y.npy": npy(np.array([object()] * n))}),
                   "allow_pickle=False"),
        "NPY shape 2**36": (npz_replace(valid, {"x.npy": shape_header}),
                            "549,755,813,888 bytes"),
        "frame_json not JSON": (npz_replace(valid, {"frame_json.npy": npy(np.array("{"))}),
                                "not JSON"),
    }


def flip(data: bytes, positions: list[int], values: list[int]) -> bytes:
    out = bytearray(data)
    for at, value in zip(positions, values):
        if out:
            out[at % len(out)] = value
    return bytes(out)


def manifest_text(data: dict) -> str:
    return json.dumps(data, indent=1)
