"""A small ctypes binding to the Embree 4 library that the ``embreex`` wheel installs.

embreex casts rays one Python call at a time; compiled code (the numba kernels of
:mod:`lidarsim_core.kernels.embree_cast`) can instead call Embree's ``rtcIntersect1`` and its
packet variants ``rtcIntersect4/8/16`` directly, with the GIL released, if it has the
functions' addresses and a scene. This module finds the shared library that embreex ships
(``embreex.libs/libembree4-*.so.4`` in its wheel), loads it with :mod:`ctypes`, builds a
triangle scene exactly as embreex 4.4 does (the robust scene flag, Embree's default build
quality, one triangle geometry with three unshared vertices per face, 16-byte vertex stride)
and hands out the addresses.

The ray/hit structures that those functions read and write are not fixed by Embree's API:
``RTCHit`` ends in ``instID[RTC_MAX_INSTANCE_LEVEL_COUNT]`` and, from Embree 4.3 built with
instance arrays (the default), ``instPrimID[...]``, so ``RTCRayHit`` is 80 or 96 bytes, and a
wrong size makes Embree write past the caller's buffer. :class:`RayHitLayout` gives the layout
this module assumes for the library's version (``rtcGetDeviceProperty``:
``RTC_DEVICE_PROPERTY_VERSION_MAJOR``/``MINOR``/``PATCH``), and :func:`load` then checks it
on the library itself: it casts a ray that hits a triangle, single and in packets of 4, 8 and
16, into buffers twice the expected size filled with a marker, and requires Embree to have
written exactly the expected hit words and nothing after them. A library whose version or
behaviour does not match raises :class:`~lidarsim_core.base.errors.BackendError` naming it.
"""

from __future__ import annotations

import ctypes
import functools
import importlib.metadata
import importlib.util
import threading
import weakref
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..base.errors import BackendError

# enum values of the Embree 4 headers (rtcore_device.h, rtcore_scene.h, rtcore_geometry.h,
# rtcore_buffer.h, rtcore_common.h)
RTC_DEVICE_PROPERTY_VERSION_MAJOR = 1
RTC_DEVICE_PROPERTY_VERSION_MINOR = 2
RTC_DEVICE_PROPERTY_VERSION_PATCH = 3
RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED = 32
RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED = 33
RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED = 34
RTC_SCENE_FLAG_NONE = 0
RTC_SCENE_FLAG_ROBUST = 1 << 2
RTC_GEOMETRY_TYPE_TRIANGLE = 0
RTC_BUFFER_TYPE_INDEX = 0
RTC_BUFFER_TYPE_VERTEX = 1
RTC_FORMAT_UINT3 = 0x5003
RTC_FORMAT_FLOAT3 = 0x9003
RTC_INVALID_GEOMETRY_ID = 0xFFFFFFFF
RTC_ERROR_NONE = 0

#: What embreex 4.x sets on every ray it casts (``EmbreeScene.run``): tnear 0, tfar the
#: float32 of 1e37, time 0, mask all ones, flags 0.
RAY_TFAR = np.float32(1e37)
RAY_MASK = 0xFFFFFFFF

#: Packet widths with an ``rtcIntersectN`` entry point.
PACKET_WIDTHS = (1, 4, 8, 16)

#: (RTC_MAX_INSTANCE_LEVEL_COUNT, instance-array fields) of the Embree 4 releases whose
#: ray/hit layout is known: the official builds use one instance level, and 4.3 added the
#: instance-array geometry and with it ``RTCHit.instPrimID``.
KNOWN_LAYOUTS = {0: (1, False), 1: (1, False), 2: (1, False), 3: (1, True), 4: (1, True)}

#: Marker written around the probe's rays (a NaN pattern Embree never writes).
_MARK = 0x7FBADBAD


@dataclass(frozen=True)
class RayHitLayout:
    """Word layout (4-byte words) of ``RTCRayHit`` and ``RTCRayHitN`` for one Embree build.

    A packet of width N stores each field as N consecutive words (``RTCRayN``: org_x, org_y,
    org_z, tnear, dir_x, dir_y, dir_z, time, tfar, mask, id, flags; then ``RTCHitN``: Ng_x,
    Ng_y, Ng_z, u, v, primID, geomID, instID[levels], instPrimID[levels] when present), so lane
    ``i`` of field ``k`` is word ``k * N + i``; a single ray is the packet of width 1, padded
    to 16 bytes (``RTC_ALIGN(16)``).
    """

    #: RTC_MAX_INSTANCE_LEVEL_COUNT of the build
    instance_levels: int
    #: whether ``RTCHit`` has ``instPrimID`` (Embree ≥ 4.3 built with instance arrays)
    instance_array: bool

    @property
    def hit_fields(self) -> int:
        """Fields of ``RTCHit``: Ng (3), u, v, primID, geomID and the instance stacks."""
        return 7 + self.instance_levels * (2 if self.instance_array else 1)

    @property
    def fields(self) -> int:
        """Fields of ``RTCRayHit``: the 12 of ``RTCRay`` and those of ``RTCHit``."""
        return 12 + self.hit_fields

    def words(self, width: int) -> int:
        """Size of ``RTCRayHit`` (width 1) or ``RTCRayHitN`` in 4-byte words."""
        if width == 1:
            return -(-self.fields // 4) * 4  # RTC_ALIGN(16) on RTCRay and RTCHit
        return self.fields * width

    def nbytes(self, width: int) -> int:
        """Size in bytes (``sizeof(RTCRayHit)``: 80 or 96 for the official 4.x builds)."""
        return 4 * self.words(width)

    @staticmethod
    def alignment(width: int) -> int:
        """Alignment in bytes Embree requires of the structure (16, 16, 32, 64)."""
        return max(16, 4 * width)


@dataclass(frozen=True)
class EmbreeLibrary:
    """The loaded Embree 4 library: its path, version, layout, one device and the addresses
    of the intersect functions (for compiled callers)."""

    path: Path
    version: tuple[int, int, int]
    layout: RayHitLayout
    #: native packet widths this CPU and build trace as packets (others are emulated)
    native_packets: tuple[int, ...]
    lib: ctypes.CDLL
    device: int
    #: ``{1: rtcIntersect1, 4: rtcIntersect4, 8: rtcIntersect8, 16: rtcIntersect16}``
    intersect: dict[int, int]

    @property
    def packet_width(self) -> int:
        """The fastest call: the widest packet this CPU traces natively (16, 8 or 4), else
        single rays (on the 2-core AVX-512 machine, per ray on the demo's rays: embreex 35 ns,
        ``rtcIntersect1`` 31 ns, packets of 4 / 8 / 16 rays 23 / 21 / 19 ns)."""
        return next((w for w in (16, 8, 4) if w in self.native_packets), 1)

    @property
    def version_text(self) -> str:
        return ".".join(map(str, self.version))

    def new_scene(self, triangles: np.ndarray, *, robust: bool = True) -> "EmbreeScene":
        """A committed scene of ``triangles`` ((F, 3, 3) float32 vertices, as embreex's
        ``TriangleMesh``), robust traversal as embreex's default ``EmbreeScene()``."""
        return EmbreeScene(self, triangles, robust=robust)

    def check_error(self, what: str) -> None:
        code = self.lib.rtcGetDeviceError(self.device)
        if code != RTC_ERROR_NONE:
            raise BackendError(f"Embree {self.version_text} failed to {what} (RTCError {code}; "
                               f"library {self.path})")


class EmbreeScene:
    """An Embree scene of one triangle mesh, committed and owned: released when this object is
    collected. The vertex and index arrays Embree reads are shared with it and kept here.

    Attributes
    ----------
    handle
        The ``RTCScene`` pointer as an integer (for compiled callers).
    """

    def __init__(self, library: EmbreeLibrary, triangles: np.ndarray, *,
                 robust: bool = True) -> None:
        tri = np.asarray(triangles)
        if tri.ndim != 3 or tri.shape[1:] != (3, 3):
            raise ValueError(f"triangles must have shape (F, 3, 3), not {tri.shape}")
        n_faces = len(tri)
        if n_faces == 0 or n_faces >= RTC_INVALID_GEOMETRY_ID // 3:
            raise BackendError(f"an Embree scene needs 1 to {RTC_INVALID_GEOMETRY_ID // 3 - 1} "
                               f"triangles, not {n_faces}")
        self.library = library
        # three unshared vertices per face, stride 16 bytes, as embreex's TriangleMesh
        self._vertices = np.zeros((3 * n_faces, 4), dtype=np.float32)
        self._vertices[:, :3] = tri.reshape(-1, 3)
        self._indices = np.arange(3 * n_faces, dtype=np.uint32).reshape(n_faces, 3)
        lib, device = library.lib, library.device
        scene = lib.rtcNewScene(device)
        if not scene:
            library.check_error("create a scene")
        self.handle: int = scene
        # the scene is released with this object, even when the build below fails
        self._finalizer = weakref.finalize(self, lib.rtcReleaseScene, scene)
        lib.rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST if robust else RTC_SCENE_FLAG_NONE)
        geometry = lib.rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE)
        if not geometry:
            library.check_error("create a triangle geometry")
        try:
            lib.rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                           self._vertices.ctypes.data, 0, 16, 3 * n_faces)
            lib.rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                           self._indices.ctypes.data, 0, 12, n_faces)
            lib.rtcCommitGeometry(geometry)
            lib.rtcAttachGeometry(scene, geometry)
        finally:
            lib.rtcReleaseGeometry(geometry)  # the scene holds its own reference
        lib.rtcCommitScene(scene)
        library.check_error(f"build the scene of {n_faces} triangles")
        self.n_faces = n_faces

    def release(self) -> None:
        """Release the Embree scene now (also done when the object is collected)."""
        self._finalizer()

    def faces(self, origins: np.ndarray, directions: np.ndarray, width: int = 1) -> np.ndarray:
        """The face each float32 ray hits first (-1 for a miss), as ``embreex``'s
        ``EmbreeScene.run(origins, directions)``, traced by the compiled kernel in packets of
        ``width`` (1, 4, 8 or 16) rays."""
        from ..kernels.embree_cast import cast_faces

        if width not in PACKET_WIDTHS:
            raise ValueError(f"width must be one of {PACKET_WIDTHS}, not {width}")
        o32 = np.ascontiguousarray(origins, dtype=np.float32)
        d32 = np.ascontiguousarray(directions, dtype=np.float32)
        if o32.shape != d32.shape or o32.ndim != 2 or o32.shape[1:] != (3,):
            raise ValueError("origins and directions must both have shape (N, 3)")
        out = np.empty(len(o32), dtype=np.int32)
        lib = self.library
        cast_faces(lib.intersect[width], self.handle, width, lib.layout.fields,
                   o32, d32, out)
        return out


def library_path() -> Path:
    """The Embree 4 shared library installed with embreex (``embreex.libs/libembree4*`` of
    its wheel on Linux, ``embreex/.dylibs`` on macOS, ``embree4.dll`` on Windows).

    Raises
    ------
    BackendError
        embreex is not installed, or its installation holds no Embree 4 library.
    """
    try:
        dist = importlib.metadata.distribution("embreex")
    except importlib.metadata.PackageNotFoundError:
        raise BackendError("embreex is not installed, so there is no Embree library to load; "
                           "pip install 'lidarsim-core[embree]'") from None
    candidates = [Path(str(f.locate())) for f in dist.files or ()
                  if Path(str(f)).name.lower().startswith(("libembree4", "embree4"))
                  and any(s in Path(str(f)).name.lower() for s in (".so", ".dylib", ".dll"))]
    if not candidates:  # installed without a RECORD of its files: look beside the package
        spec = importlib.util.find_spec("embreex")
        if spec is not None and spec.origin is not None:
            package = Path(spec.origin).parent
            for folder in (package.parent / "embreex.libs", package / ".dylibs", package):
                candidates += sorted(folder.glob("*embree4*"))
    found = [p for p in candidates if p.is_file()]
    if not found:
        raise BackendError(f"embreex {dist.version} is installed without an Embree 4 library "
                           "(libembree4*); an Embree 4 build of embreex (≥ 4.0) is needed")
    return found[0]


def _declare(lib: ctypes.CDLL) -> None:
    """Argument and result types of the functions used (rtcore_*.h of Embree 4)."""
    p, u, i, size = ctypes.c_void_p, ctypes.c_uint, ctypes.c_int, ctypes.c_size_t
    signatures = {
        "rtcNewDevice": (p, [ctypes.c_char_p]),
        "rtcReleaseDevice": (None, [p]),
        "rtcGetDeviceProperty": (ctypes.c_ssize_t, [p, i]),
        "rtcGetDeviceError": (i, [p]),
        "rtcNewScene": (p, [p]),
        "rtcSetSceneFlags": (None, [p, i]),
        "rtcCommitScene": (None, [p]),
        "rtcReleaseScene": (None, [p]),
        "rtcNewGeometry": (p, [p, i]),
        "rtcSetSharedGeometryBuffer": (None, [p, i, u, i, p, size, size, size]),
        "rtcCommitGeometry": (None, [p]),
        "rtcAttachGeometry": (u, [p, p]),
        "rtcReleaseGeometry": (None, [p]),
        "rtcIntersect1": (None, [p, p, p]),
        "rtcIntersect4": (None, [p, p, p, p]),
        "rtcIntersect8": (None, [p, p, p, p]),
        "rtcIntersect16": (None, [p, p, p, p]),
    }
    for name, (restype, argtypes) in signatures.items():
        try:
            func = getattr(lib, name)
        except AttributeError:
            raise BackendError(f"the Embree library {lib._name} has no function {name}; "
                               "an Embree 4 library is needed") from None
        func.restype, func.argtypes = restype, argtypes


def _aligned(words: int, alignment: int) -> np.ndarray:
    """``words`` uint32 words starting at an address that is a multiple of ``alignment``."""
    raw = np.empty(words + alignment // 4, dtype=np.uint32)
    skip = (-raw.ctypes.data % alignment) // 4
    return raw[skip:skip + words]


def _probe_layout(library: EmbreeLibrary) -> None:
    """Cast a ray that hits a triangle through each intersect function into a buffer twice the
    assumed size, filled with a marker, and check that Embree wrote the hit (primID, geomID,
    the instance stack) and nothing after the assumed end of the structure."""
    layout = library.layout
    scene = library.new_scene(np.array([[[-1, -1, 0], [1, -1, 0], [0, 1, 0]]], np.float32))
    lib = library.lib
    for width in PACKET_WIDTHS:
        words = layout.words(width)
        buf = _aligned(2 * words + 16, layout.alignment(width))
        buf[:] = _MARK
        floats = buf.view(np.float32)
        for lane in range(width):
            for field, value in enumerate((0.0, 0.0, -5.0, 0.0, 0.0, 0.0, 1.0, 0.0, RAY_TFAR)):
                floats[field * width + lane] = value
            buf[9 * width + lane] = RAY_MASK
            buf[10 * width + lane] = 0
            buf[11 * width + lane] = 0
            buf[17 * width + lane] = RTC_INVALID_GEOMETRY_ID  # primID
            buf[18 * width + lane] = RTC_INVALID_GEOMETRY_ID  # geomID
        # Ng, u, v and the instance stacks keep the marker: the hit must overwrite them all
        lanes = np.arange(width)
        hit_words = np.concatenate([field * width + lanes
                                    for field in range(12, 12 + layout.hit_fields)])
        stack_words = hit_words[7 * width:]
        if width == 1:
            lib.rtcIntersect1(scene.handle, buf.ctypes.data, None)
        else:
            valid = _aligned(width, layout.alignment(width)).view(np.int32)
            valid[:] = -1
            getattr(lib, f"rtcIntersect{width}")(valid.ctypes.data, scene.handle,
                                                 buf.ctypes.data, None)
        library.check_error(f"cast the layout probe's rays (packets of {width})")
        ok = (np.all(buf[words:] == _MARK)  # nothing written past the structure
              and np.all(buf[hit_words] != _MARK)  # every hit field written
              and np.all(buf[17 * width + lanes] == 0) and np.all(buf[18 * width + lanes] == 0)
              and np.all(buf[stack_words] == RTC_INVALID_GEOMETRY_ID)
              and np.allclose(floats[8 * width + lanes], 5.0))
        if not ok:
            scene.release()
            raise BackendError(
                f"Embree {library.version_text} ({library.path}) does not use the ray/hit "
                f"layout assumed for its version ({layout.nbytes(width)}-byte RTCRayHit"
                f"{'' if width == 1 else width}: {layout.instance_levels} instance level(s), "
                f"instPrimID {'present' if layout.instance_array else 'absent'}); "
                "it cannot be called from compiled code safely")
    scene.release()


_LOAD_LOCK = threading.Lock()


@functools.lru_cache(maxsize=1)
def _load_cached() -> EmbreeLibrary:
    path = library_path()
    try:
        lib = ctypes.CDLL(str(path))
    except OSError as exc:
        raise BackendError(f"cannot load the Embree library {path}: {exc}") from None
    _declare(lib)
    device = lib.rtcNewDevice(None)
    if not device:
        raise BackendError(f"the Embree library {path} could not create a device")
    version = tuple(lib.rtcGetDeviceProperty(device, prop) for prop in (
        RTC_DEVICE_PROPERTY_VERSION_MAJOR, RTC_DEVICE_PROPERTY_VERSION_MINOR,
        RTC_DEVICE_PROPERTY_VERSION_PATCH))
    if version[0] != 4 or version[1] not in KNOWN_LAYOUTS:
        lib.rtcReleaseDevice(device)
        known = ", ".join(f"4.{minor}" for minor in KNOWN_LAYOUTS)
        raise BackendError(f"the Embree library {path} is version {'.'.join(map(str, version))}"
                           f"; its ray/hit structure layout is known for Embree {known} only")
    native = tuple(w for w, prop in ((4, RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED),
                                     (8, RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED),
                                     (16, RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED))
                   if lib.rtcGetDeviceProperty(device, prop))
    addresses = {w: ctypes.cast(getattr(lib, f"rtcIntersect{w}"), ctypes.c_void_p).value
                 for w in PACKET_WIDTHS}
    library = EmbreeLibrary(path, version, RayHitLayout(*KNOWN_LAYOUTS[version[1]]), native,
                            lib, device, addresses)
    _probe_layout(library)
    return library


def load() -> EmbreeLibrary:
    """The Embree 4 library of embreex, loaded once per process, its layout checked.

    Raises
    ------
    BackendError
        embreex or its Embree 4 library is missing, or the library's version or ray/hit
        layout is not one this binding knows (the message names the library and version).
    """
    with _LOAD_LOCK:
        return _load_cached()


def available() -> tuple[bool, str]:
    """Whether :func:`load` succeeds here, and why not."""
    try:
        load()
    except BackendError as exc:
        return False, str(exc)
    return True, ""
