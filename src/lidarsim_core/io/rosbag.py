"""ROS 2 bags: every frame of a scenario in one rosbag2 MCAP file (extra ``ros``: rosbags).

Written with `rosbags <https://gitlab.com/ternaris/rosbags>`_ (pure Python, no ROS
installation) and its ROS 2 Humble type store; the MCAP file carries the message definitions
and rosbag2's metadata record, so it is a complete bag by itself. Topics:

==================================  ==========================================================
topic                               messages
==================================  ==========================================================
``/lidarsim/points``                ``sensor_msgs/msg/PointCloud2``, one per frame; header
                                    stamp = frame start (seconds from the scenario epoch),
                                    ``frame_id`` = the sensor frame (:data:`SENSOR_FRAME`)
``/tf``                             ``tf2_msgs/msg/TFMessage`` at every frame start:
                                    scene → sensor and scene → each target
``/lidarsim/ground_truth/<target>`` ``geometry_msgs/msg/PoseStamped``: the target's body frame
                                    in the sensor frame at frame start (``targets_in_sensor``)
``/livox/lidar`` (option ``livox``) ``livox_ros_driver2/msg/CustomMsg`` (FAST-LIO and other
                                    Livox pipelines subscribe to it)
==================================  ==========================================================

The PointCloud2 fields (:data:`POINT_FIELDS_ROS`) are x, y, z, intensity (float32, as ROS
LiDAR drivers publish), ``t`` (uint32 ns after the header stamp, as the Livox and Ouster
drivers), ``ring`` (channel, uint16), ``return_number`` and ``number_of_returns`` (uint8),
``label`` (part, uint32 as ``pcl::PointXYZL``), then the rest of the point record:
``target`` (int16), ``detected`` (uint8), ``face_index`` (int32), and the float64 ground truth
and geometry (``x_true``.., ``range``, ``range_true``, ``azimuth``, ``elevation``,
``timestamp``, ``incidence_angle``) and ``ray_index`` (float64: PointField has no 64-bit
integer; exact below 2**53). Offsets follow natural alignment.

The scene and target frame names come from the scenario: ``scene`` and each target's name.
"""

from __future__ import annotations

import math
import os
import secrets
import shutil
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable, Sequence

import numpy as np

from ..base.errors import ConfigError, OutputError, UserInputError
from ..base.optional import require

if TYPE_CHECKING:
    from ..records.pointcloud import FrameInfo, PointCloud

#: TF frame of the scenario's scene (the LVLH frame for orbital scenarios).
SCENE_FRAME = "scene"
#: TF frame of the sensor (+X boresight, +Y left, +Z up).
SENSOR_FRAME = "sensor"
POINTS_TOPIC = "/lidarsim/points"
TF_TOPIC = "/tf"
GROUND_TRUTH_TOPIC = "/lidarsim/ground_truth/{target}"
LIVOX_TOPIC = "/livox/lidar"

#: PointCloud2 field name, point-record column it holds, NumPy dtype, in message order.
POINT_FIELDS_ROS: tuple[tuple[str, str, str], ...] = (
    ("x", "x", "<f4"), ("y", "y", "<f4"), ("z", "z", "<f4"), ("intensity", "intensity", "<f4"),
    ("t", "timestamp", "<u4"), ("ring", "channel", "<u2"),
    ("return_number", "return_number", "u1"), ("number_of_returns", "number_of_returns", "u1"),
    ("label", "part", "<u4"), ("target", "target", "<i2"), ("detected", "detected", "u1"),
    ("face_index", "face_index", "<i4"),
    ("x_true", "x_true", "<f8"), ("y_true", "y_true", "<f8"), ("z_true", "z_true", "<f8"),
    ("range", "range", "<f8"), ("range_true", "range_true", "<f8"),
    ("azimuth", "azimuth", "<f8"), ("elevation", "elevation", "<f8"),
    ("timestamp", "timestamp", "<f8"), ("incidence_angle", "incidence_angle", "<f8"),
    ("ray_index", "ray_index", "<f8"),
)
#: NumPy dtype → ``sensor_msgs/msg/PointField`` datatype constant.
_POINTFIELD_TYPES = {"i1": 1, "u1": 2, "<i2": 3, "<u2": 4, "<i4": 5, "<u4": 6, "<f4": 7,
                     "<f8": 8}

#: The Livox driver's message definitions (livox_ros_driver2, MIT licence: field layout only).
LIVOX_CUSTOM_POINT_MSG = """\
uint32 offset_time
float32 x
float32 y
float32 z
uint8 reflectivity
uint8 tag
uint8 line
"""
LIVOX_CUSTOM_MSG = """\
std_msgs/Header header
uint64 timebase
uint32 point_num
uint8 lidar_id
uint8[3] rsvd
CustomPoint[] points
"""


def require_rosbags() -> Any:
    for module in ("rosbags.rosbag2", "rosbags.typesys"):
        require(module, extra="ros", what="writing ROS 2 bags", error=OutputError)
    return sys.modules["rosbags"]


def typestore(livox: bool = False) -> Any:
    """The ROS 2 Humble type store, with the Livox driver's messages registered if asked."""
    require_rosbags()
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    if livox:
        types = {}
        types.update(get_types_from_msg(LIVOX_CUSTOM_POINT_MSG,
                                        "livox_ros_driver2/msg/CustomPoint"))
        types.update(get_types_from_msg(LIVOX_CUSTOM_MSG, "livox_ros_driver2/msg/CustomMsg"))
        store.register(types)
    return store


def _ns(seconds: float) -> int:
    return int(round(seconds * 1e9))


def _stamp(store: Any, seconds: float) -> Any:
    ns = _ns(seconds)
    return store.types["builtin_interfaces/msg/Time"](sec=ns // 10 ** 9, nanosec=ns % 10 ** 9)


def _header(store: Any, seconds: float, frame_id: str) -> Any:
    return store.types["std_msgs/msg/Header"](stamp=_stamp(store, seconds), frame_id=frame_id)


def _pose_parts(store: Any, q: Sequence[float], r: Sequence[float]) -> tuple[Any, Any]:
    return (store.types["geometry_msgs/msg/Vector3"](x=r[0], y=r[1], z=r[2]),
            store.types["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]))


def point_record_dtype() -> np.dtype:
    """The packed PointCloud2 point (naturally aligned) as a NumPy structured dtype."""
    return np.dtype([(name, dtype) for name, _, dtype in POINT_FIELDS_ROS], align=True)


def pointcloud2(store: Any, cloud: "PointCloud", frame_id: str = SENSOR_FRAME) -> Any:
    """The ``sensor_msgs/msg/PointCloud2`` of one frame (see the module docstring)."""
    types = store.types
    dtype = point_record_dtype()
    n = len(cloud)
    data = np.zeros(n, dtype=dtype)
    start = cloud.frame.t_start
    offsets = np.round((cloud["timestamp"] - start) * 1e9)
    if n and (offsets.min() < 0 or offsets.max() > np.iinfo(np.uint32).max):
        raise OutputError("point times do not fit PointCloud2's uint32 ns field 't' (frames "
                          "longer than 4.29 s)", field="timestamp")
    for name, column, out in POINT_FIELDS_ROS:
        values = offsets if name == "t" else cloud[column]
        if np.dtype(out).kind in "iu" and n and np.dtype(values.dtype).kind in "iu":
            info = np.iinfo(out)
            if values.min() < info.min or values.max() > info.max:
                raise OutputError(f"column '{column}' does not fit PointCloud2 field '{name}' "
                                  f"({np.dtype(out).name})", field=column)
        data[name] = values
    fields = [types["sensor_msgs/msg/PointField"](
        name=name, offset=dtype.fields[name][1], datatype=_POINTFIELD_TYPES[out], count=1)
        for name, _, out in POINT_FIELDS_ROS]
    return types["sensor_msgs/msg/PointCloud2"](
        header=_header(store, start, frame_id), height=1, width=n, fields=fields,
        is_bigendian=False, point_step=dtype.itemsize, row_step=dtype.itemsize * n,
        data=np.frombuffer(data.tobytes(), dtype=np.uint8),
        is_dense=bool(n == 0 or np.all(np.isfinite(cloud.xyz))))


def livox_reflectivity(intensity: np.ndarray) -> np.ndarray:
    """Livox's 8-bit reflectivity from apparent reflectivity: 0..150 for diffuse 0..100 %,
    151..255 for brighter returns (glints, retro-reflectors; linear up to 2, then 255)."""
    value = np.asarray(intensity, dtype=np.float64)
    diffuse = np.round(150.0 * np.clip(value, 0.0, 1.0))
    bright = 151.0 + np.round(104.0 * np.clip(value - 1.0, 0.0, 1.0))
    return np.where(value > 1.0, bright, diffuse).astype(np.uint8)


def livox_custom_msg(store: Any, cloud: "PointCloud", frame_id: str = SENSOR_FRAME) -> Any:
    """The ``livox_ros_driver2/msg/CustomMsg`` of one frame: ``timebase`` = frame start (ns),
    ``offset_time`` per point, ``line`` = channel, ``tag`` bits 4-5 = return number - 1."""
    types = store.types
    point = types["livox_ros_driver2/msg/CustomPoint"]
    start = cloud.frame.t_start
    offsets = np.round((cloud["timestamp"] - start) * 1e9).astype(np.int64)
    refl = livox_reflectivity(cloud["intensity"])
    tags = ((np.clip(cloud["return_number"].astype(np.int64) - 1, 0, 3) & 3) << 4)
    lines = np.clip(cloud["channel"].astype(np.int64), 0, 255)
    xyz = cloud.xyz.astype(np.float32)
    points = [point(offset_time=int(o), x=float(p[0]), y=float(p[1]), z=float(p[2]),
                    reflectivity=int(r), tag=int(g), line=int(li))
              for o, p, r, g, li in zip(offsets.tolist(), xyz, refl.tolist(), tags.tolist(),
                                        lines.tolist())]
    return types["livox_ros_driver2/msg/CustomMsg"](
        header=_header(store, start, frame_id), timebase=_ns(start), point_num=len(points),
        lidar_id=0, rsvd=np.zeros(3, dtype=np.uint8), points=points)


def tf_message(store: Any, frame: "FrameInfo") -> Any:
    """``tf2_msgs/msg/TFMessage`` at frame start: scene → sensor and scene → every target
    (the poses of ``lidarsim poses``, quaternions with w >= 0)."""
    from ..records.groundtruth import frame_record

    types = store.types
    record = frame_record(frame)
    poses = [(SENSOR_FRAME, record["q_sensor_in_scene"], record["r_sensor_in_scene_m"])]
    poses += [(t["name"], t["q_target_in_scene"], t["r_target_in_scene_m"])
              for t in record["targets"]]
    transforms = []
    for child, q, r in poses:
        translation, rotation = _pose_parts(store, q, r)
        transforms.append(types["geometry_msgs/msg/TransformStamped"](
            header=_header(store, frame.t_start, SCENE_FRAME), child_frame_id=child,
            transform=types["geometry_msgs/msg/Transform"](translation=translation,
                                                           rotation=rotation)))
    return types["tf2_msgs/msg/TFMessage"](transforms=transforms)


def ground_truth_messages(store: Any, frame: "FrameInfo") -> list[Any]:
    """``geometry_msgs/msg/PoseStamped`` of every target in the sensor frame at frame start
    (the ``q_target_in_sensor`` / ``r_target_in_sensor_m`` of ``lidarsim poses``)."""
    from ..records.groundtruth import frame_record

    types = store.types
    out = []
    for target in frame_record(frame)["targets"]:
        r, q = target["r_target_in_sensor_m"], target["q_target_in_sensor"]
        out.append(types["geometry_msgs/msg/PoseStamped"](
            header=_header(store, frame.t_start, SENSOR_FRAME),
            pose=types["geometry_msgs/msg/Pose"](
                position=types["geometry_msgs/msg/Point"](x=r[0], y=r[1], z=r[2]),
                orientation=_pose_parts(store, q, r)[1])))
    return out


def check_target_names(names: Sequence[str]) -> None:
    reserved = {SCENE_FRAME, SENSOR_FRAME}
    for name in names:
        if name in reserved:
            raise OutputError(f"target name '{name}' is also a TF frame of the bag "
                              f"({', '.join(sorted(reserved))}); rename the target",
                              field="targets.name")
        if not name or any(c in name for c in " /\\\t\n"):
            raise OutputError(f"target name {name!r} cannot be a ROS topic and TF frame name "
                              "(no spaces or slashes)", field="targets.name")


#: ROS 2 ``builtin_interfaces/Time.sec`` is a signed 32-bit integer.
_ROS_SECONDS = (-2 ** 31, 2 ** 31 - 1)


def check_bag_frames(infos: Iterable[Any], *, source: str | Path | None = None) -> None:
    """Refuse, before anything is simulated, frames a bag cannot hold: a time outside ROS's
    signed 32-bit seconds (``scan.start_s: 3e9``), or a frame whose one ``PointCloud2``
    message would exceed the ``bag_frame_points`` limit (a message holds a whole frame in
    memory, several times over while it is serialised: a bag cannot stream one frame).

    Raises
    ------
    ConfigError
        Naming the scenario field.
    """
    from ..base.limits import check

    for info in infos:
        for seconds in (info.t_start, info.t_end):
            if not (math.isfinite(seconds) and
                    _ROS_SECONDS[0] <= math.floor(seconds) <= _ROS_SECONDS[1]):
                raise ConfigError(f"frame {info.frame} is at t = {seconds:g} s, outside the "
                                  "seconds a ROS 2 time stamp holds (a signed 32-bit integer, "
                                  f"±{2 ** 31:,} s)", source=source,
                                  field="scan.start_s")
        check("bag_frame_points", info.rays_emitted, source=source, field="scan",
              what=f"frame {info.frame} of a ROS 2 bag (one message holds the whole frame)")


def check_bag_output(path: str | Path, *, overwrite: bool = False) -> Path:
    """Raise :class:`OutputError` unless a bag can be written to ``path`` (the one overwrite
    policy of :mod:`lidarsim_core.base.outputs`); returns it."""
    from ..base.outputs import check_file

    check_file(path, overwrite=overwrite)
    return Path(path)


def write_bag(clouds: Iterable["PointCloud"], path: str | Path, *, target_names: Sequence[str],
              overwrite: bool = False, livox: bool = False,
              on_frame: Callable[[int, "PointCloud"], None] | None = None) -> Path:
    """Write the frames ``clouds`` yields (e.g. a simulation's, one at a time) into one
    rosbag2 MCAP file at ``path``.

    The bag is assembled in a hidden temporary directory beside ``path`` and its MCAP file is
    renamed onto ``path`` only when complete: an error or interrupt leaves nothing behind.

    Parameters
    ----------
    clouds
        The frames' point clouds, in the order written (consumed one at a time).
    path
        The ``.mcap`` file to write.
    overwrite
        Replace an existing file.
    target_names
        The targets' names (one ground-truth topic each).
    livox
        Also write ``livox_ros_driver2/msg/CustomMsg`` on ``/livox/lidar``.
    on_frame
        Called with ``(frame index, cloud)`` after each frame is written (progress).

    Returns
    -------
    Path
        ``path``.
    """
    require_rosbags()
    from rosbags.rosbag2 import StoragePlugin, Writer

    from ..base.outputs import make_parent

    path = check_bag_output(path, overwrite=overwrite)
    make_parent(path)  # a missing folder is created, as for every output
    parent = path.parent if str(path.parent) else Path(".")
    target_names = list(target_names)
    check_target_names(target_names)
    store = typestore(livox)
    work = parent / f".{path.name}.{secrets.token_hex(6)}.part"
    # the bag directory inside has a fixed name: rosbag2's metadata record in the MCAP file
    # names the file after it, so the same frames give the same bytes on every run
    work.mkdir()
    try:
        with Writer(work / path.stem, version=8, storage_plugin=StoragePlugin.MCAP) as writer:
            def topic(name: str, msgtype: str) -> Any:
                return writer.add_connection(name, msgtype, typestore=store)

            points = topic(POINTS_TOPIC, "sensor_msgs/msg/PointCloud2")
            tf = topic(TF_TOPIC, "tf2_msgs/msg/TFMessage")
            truth = [topic(GROUND_TRUTH_TOPIC.format(target=name),
                           "geometry_msgs/msg/PoseStamped") for name in target_names]
            custom = topic(LIVOX_TOPIC, "livox_ros_driver2/msg/CustomMsg") if livox else None
            for cloud in clouds:
                info = cloud.frame
                stamp = _ns(info.t_start)

                def put(connection: Any, message: Any) -> None:
                    writer.write(connection, stamp,
                                 store.serialize_cdr(message, message.__msgtype__))

                put(tf, tf_message(store, info))
                for connection, message in zip(truth, ground_truth_messages(store, info)):
                    put(connection, message)
                put(points, pointcloud2(store, cloud))
                if custom is not None:
                    put(custom, livox_custom_msg(store, cloud))
                if on_frame is not None:
                    on_frame(info.frame, cloud)
        files = list((work / path.stem).glob("*.mcap"))
        if len(files) != 1:
            raise OutputError(f"the bag writer produced {len(files)} MCAP files, expected 1",
                              source=path)
        os.replace(files[0], path)
    except Exception as exc:  # ENOSPC inside the bag writer: one line naming the bag
        cause = exc if isinstance(exc, OSError) else exc.__cause__ or exc.__context__
        if isinstance(cause, OSError) and not isinstance(exc, UserInputError):
            from ..base.oserrors import describe_os_error

            raise OutputError(f"cannot write the bag: {describe_os_error(cause)}",
                              source=path) from exc
        raise
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return path
