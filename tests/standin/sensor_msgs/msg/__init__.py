"""``sensor_msgs/msg``: ``Image``, ``CameraInfo`` and its ``RegionOfInterest``, with rclpy's
field types (``Image.data`` an ``array.array('B')``, ``CameraInfo.k`` nine float64 values)."""

from __future__ import annotations

from array import array
from dataclasses import dataclass, field

import numpy as np
from std_msgs.msg import Header


@dataclass
class Image:
    header: Header = field(default_factory=Header)
    height: int = 0
    width: int = 0
    encoding: str = ""
    is_bigendian: int = 0
    step: int = 0
    data: array = field(default_factory=lambda: array("B"))


@dataclass
class RegionOfInterest:
    x_offset: int = 0
    y_offset: int = 0
    height: int = 0
    width: int = 0
    do_rectify: bool = False


@dataclass
class CameraInfo:
    header: Header = field(default_factory=Header)
    height: int = 0
    width: int = 0
    distortion_model: str = ""
    d: array = field(default_factory=lambda: array("d"))
    k: np.ndarray = field(default_factory=lambda: np.zeros(9))
    r: np.ndarray = field(default_factory=lambda: np.zeros(9))
    p: np.ndarray = field(default_factory=lambda: np.zeros(12))
    binning_x: int = 0
    binning_y: int = 0
    roi: RegionOfInterest = field(default_factory=RegionOfInterest)
