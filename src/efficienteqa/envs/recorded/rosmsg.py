"""The ROS 2 message types a recorded walk uses, as an MCAP file's schemas hold them: each
type's ``.msg`` definition followed by those of the types it uses (the ``ros2msg`` schema
encoding that ``ros2 bag record`` writes)."""

from __future__ import annotations

IMAGE = "sensor_msgs/msg/Image"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
STRING = "std_msgs/msg/String"

# Colour, depth and instance encodings read (sensor_msgs/image_encodings.hpp names).
COLOUR_ENCODINGS = ("rgb8", "bgr8", "rgba8", "bgra8")
DEPTH_ENCODINGS = ("16UC1", "mono16", "32FC1")
INSTANCE_ENCODING = "32SC1"

_SEPARATOR = "=" * 80

_TIME = "int32 sec\nuint32 nanosec\n"
_HEADER = "builtin_interfaces/Time stamp\nstring frame_id\n"


def _with(main: str, *used: tuple[str, str]) -> str:
    return main + "".join(f"{_SEPARATOR}\nMSG: {name}\n{text}" for name, text in used)


DEFINITIONS = {
    IMAGE: _with("std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n"
                 "uint8 is_bigendian\nuint32 step\nuint8[] data\n",
                 ("std_msgs/Header", _HEADER), ("builtin_interfaces/Time", _TIME)),
    CAMERA_INFO: _with("std_msgs/Header header\nuint32 height\nuint32 width\n"
                       "string distortion_model\nfloat64[] d\nfloat64[9] k\nfloat64[9] r\n"
                       "float64[12] p\nuint32 binning_x\nuint32 binning_y\n"
                       "sensor_msgs/RegionOfInterest roi\n",
                       ("std_msgs/Header", _HEADER), ("builtin_interfaces/Time", _TIME),
                       ("sensor_msgs/RegionOfInterest", "uint32 x_offset\nuint32 y_offset\n"
                        "uint32 height\nuint32 width\nbool do_rectify\n")),
    TF_MESSAGE: _with("geometry_msgs/TransformStamped[] transforms\n",
                      ("geometry_msgs/TransformStamped", "std_msgs/Header header\n"
                       "string child_frame_id\ngeometry_msgs/Transform transform\n"),
                      ("std_msgs/Header", _HEADER), ("builtin_interfaces/Time", _TIME),
                      ("geometry_msgs/Transform", "geometry_msgs/Vector3 translation\n"
                       "geometry_msgs/Quaternion rotation\n"),
                      ("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n"),
                      ("geometry_msgs/Quaternion", "float64 x 0\nfloat64 y 0\nfloat64 z 0\n"
                       "float64 w 1\n")),
    STRING: "string data\n",
}


def type_name(schema_name: str) -> str:
    """"sensor_msgs/msg/Image" for "sensor_msgs/Image" too (a converted ROS 1 bag's spelling)."""
    package, _, rest = schema_name.partition("/")
    return f"{package}/msg/{rest.rpartition('/')[2]}" if rest else schema_name


def stamp_ns(header: object) -> int:
    """A ``std_msgs/Header``'s stamp in nanoseconds."""
    stamp = header.stamp  # type: ignore[attr-defined]
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def header(stamp: int, frame_id: str) -> dict[str, object]:
    return {"stamp": {"sec": stamp // 1_000_000_000, "nanosec": stamp % 1_000_000_000},
            "frame_id": frame_id}
