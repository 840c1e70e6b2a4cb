"""sensor_msgs/Image <-> numpy BGR images, without cv_bridge (not on PyPI).

Pure module (messages and numpy; no rclpy): the camera tracker reads ``bgr8``, ``rgb8``,
``bgra8``, ``rgba8`` and ``mono8`` images; the synthetic camera publishes ``bgr8``.
"""

from __future__ import annotations

import array

import cv2
import numpy as np
from sensor_msgs.msg import Image

CHANNELS = {'bgr8': 3, 'rgb8': 3, 'bgra8': 4, 'rgba8': 4, 'mono8': 1}
TO_BGR = {'rgb8': cv2.COLOR_RGB2BGR, 'bgra8': cv2.COLOR_BGRA2BGR,
          'rgba8': cv2.COLOR_RGBA2BGR, 'mono8': cv2.COLOR_GRAY2BGR}


class ImageError(ValueError):
    """An image message the tracker cannot read; the message says what to publish."""


def image_from_msg(msg: Image) -> np.ndarray:
    """The BGR uint8 image (height, width, 3) of a sensor_msgs/Image."""
    channels = CHANNELS.get(msg.encoding)
    if channels is None:
        raise ImageError(f'encoding {msg.encoding!r} is not supported; publish one of '
                         f'{", ".join(CHANNELS)}')
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    if h <= 0 or w <= 0 or step < w * channels or len(msg.data) < h * step:
        raise ImageError(f'a {w}x{h} {msg.encoding} image with step {step} needs '
                         f'{h * step} bytes, got {len(msg.data)}')
    rows = np.frombuffer(bytes(msg.data), np.uint8, h * step).reshape(h, step)
    pixels = rows[:, :w * channels].reshape(h, w, channels) if channels > 1 else rows[:, :w]
    if msg.encoding == 'bgr8':
        return np.ascontiguousarray(pixels)
    return cv2.cvtColor(np.ascontiguousarray(pixels), TO_BGR[msg.encoding])


def image_to_msg(image: np.ndarray, stamp, frame_id: str = 'camera') -> Image:
    """A ``bgr8`` sensor_msgs/Image of a BGR uint8 image; ``stamp`` a builtin_interfaces
    Time."""
    msg = Image()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.height, msg.width = int(image.shape[0]), int(image.shape[1])
    msg.encoding = 'bgr8'
    msg.is_bigendian = 0
    msg.step = int(image.shape[1]) * 3
    # An array.array, not bytes: rclpy serializes a bytes-assigned uint8[] element by
    # element (50 ms for 640 x 480 here, against 2 ms).
    msg.data = array.array('B', np.ascontiguousarray(image, dtype=np.uint8).tobytes())
    return msg
