"""camera_tracker_node: the overhead camera of thesis 5.1 (Figs. 5.2-5.4) as robot poses.

Wiring (logic in camera_tracker.CameraTracker, pixels to metres in arena_calibration):

  image (source '')     sensor_msgs/Image (bgr8, rgb8, mono8...) -> one frame
  source /dev/videoN, N or a video file: read with cv2.VideoCapture at frame_rate
  agent_K/pose          geometry_msgs/PoseStamped (map frame, yaw CCW) per robot seen,
                        stamped with the frame's capture time: what agent_node
                        (external_pose) and bridge_node read
  camera/annotated      sensor_msgs/Image: the frame with ids, headings and flags (Fig. 5.4)
  calibration_file      camera_calibrate's YAML: the homography, and when measured the lens
                        (k1, k2: circle centres undistorted) and the colours (white
                        balance and cover_colors, which replace the fleet file's)
  /diagnostics          diagnostic_msgs/DiagnosticArray: per robot tracked / missing, and
                        the counts of frames, unreadable frames, unknown-colour covers,
                        ambiguous and incomplete covers

A robot unseen for ``missing_timeout`` is reported missing (a log line and diagnostics)
and no pose is published for it until it is seen again: never guessed. A camera that
cannot be opened or a frame that cannot be read gives one log line and is retried every
``reopen_period``. Parameters: PARAMETERS below, defaults equal to config/camera.yaml.
"""

from __future__ import annotations

import os
import sys

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from sensor_msgs.msg import Image

from swarm_agent.conversions import pose_stamped
from swarm_bridge.arena_calibration import Calibration, CalibrationError
from swarm_bridge.camera_tracker import annotate, CameraTracker, TrackerConfig, TrackerError
from swarm_bridge.image_msgs import image_from_msg, image_to_msg, ImageError
from swarm_common import qos
from swarm_common.fleet import initial_poses, load_cover_colors, load_fleet
from swarm_common.ros_support import run_node

DEFAULTS = TrackerConfig()
PARAMETERS = {
    'fleet_file': ('', 'Fleet YAML with robots, colours and cover_colors (default: package)'),
    'calibration_file': ('', 'Calibration written by camera_calibrate: homography, lens, '
                             'colours (required)'),
    'source': ('', "'' for the image topic, else a V4L2 device (/dev/videoN or N) or a "
                   'video file read with OpenCV'),
    'frame_rate': (30.0, 'Frames per second read from a device or file'),
    'reopen_period': (1.0, 'Seconds between attempts to reopen a failed camera'),
    'missing_timeout': (DEFAULTS.missing_timeout_s, 'Seconds unseen before a robot is '
                                                    'reported missing'),
    'saturation_min': (DEFAULTS.saturation_min, 'Saturation (0-255) above which a pixel is '
                                                'coloured'),
    'value_fraction': (DEFAULTS.value_fraction, 'Value threshold as a fraction of the '
                                                "image's reference brightness"),
    'hue_tolerance': (DEFAULTS.hue_tolerance, 'Hue distance (OpenCV units) to a fleet colour'),
    'max_speed': (DEFAULTS.max_speed, 'Fastest a robot can move, m/s (identity gate)'),
    'gate_m': (DEFAULTS.gate_m, 'Identity gate beyond max_speed times the elapsed time, m'),
    'initial_poses': ([0.0], 'x,y,yaw_deg per robot in fleet order: where robots of one '
                             'colour start (empty: the first frame decides)'),
    'image_reliable': (False, 'Subscribe to the image topic reliably (a publisher that is '
                              'reliable, as hil_world_node; a best-effort camera driver '
                              'then cannot connect)'),
    'publish_annotated': (True, 'Publish camera/annotated'),
    'status_period': (1.0, 'Seconds between diagnostics messages'),
}
IMAGE_QOS = {'history': qos.KEEP_LAST, 'depth': 1, 'reliability': qos.BEST_EFFORT,
             'durability': qos.VOLATILE}


class CameraTrackerNode(Node):
    """ROS wiring of a CameraTracker; see the module docstring."""

    def __init__(self, node_name: str = 'camera_tracker', **kwargs) -> None:
        super().__init__(node_name, **kwargs)
        for name, (default, text) in PARAMETERS.items():
            self.declare_parameter(name, default, ParameterDescriptor(description=text))
        p = {name: self.get_parameter(name).value for name in PARAMETERS}
        self.params = p
        if not p['calibration_file']:
            raise CalibrationError('no calibration_file: run camera_calibrate --source ... '
                                   '--out FILE first and pass -p calibration_file:=FILE')
        calibration = Calibration.load(p['calibration_file'])
        robots = load_fleet(p['fleet_file'] or None, hardware=True)
        flat = [float(v) for v in p['initial_poses']]
        initial = ({r.id: pose[:2] for r, pose in zip(robots, initial_poses(flat, robots))}
                   if len(flat) > 1 else None)
        config = TrackerConfig(saturation_min=int(p['saturation_min']),
                               value_fraction=float(p['value_fraction']),
                               hue_tolerance=float(p['hue_tolerance']),
                               max_speed=float(p['max_speed']), gate_m=float(p['gate_m']),
                               missing_timeout_s=float(p['missing_timeout']))
        try:
            self.tracker = CameraTracker(robots, load_cover_colors(p['fleet_file'] or None),
                                         calibration, config, initial_poses=initial)
        except TrackerError as exc:
            source = (p['calibration_file'] if calibration.cover_colors is not None
                      else p['fleet_file'] or 'the fleet file')
            raise TrackerError(f'{source}: {exc}') from None
        self.radius = {r.id: r.radius for r in robots}
        self.counts = {'frames': 0, 'bad_frames': 0, 'unknown_covers': 0, 'ambiguous': 0,
                       'incomplete': 0}
        self._missing: set[int] = set()
        self._problem: str | None = None
        self._capture = None
        sensor = QoSProfile(**qos.SENSOR)
        self._pose_pubs = {r.id: self.create_publisher(
            PoseStamped, f'agent_{r.id}/pose', sensor) for r in robots}
        self._annotated = (self.create_publisher(Image, 'camera/annotated',
                                                 QoSProfile(**IMAGE_QOS))
                           if p['publish_annotated'] else None)
        self._diag = self.create_publisher(DiagnosticArray, '/diagnostics',
                                           QoSProfile(**qos.STATE))
        if p['source']:
            self._open()
            self.create_timer(1.0 / float(p['frame_rate']), self._on_capture_timer)
            self.create_timer(float(p['reopen_period']), self._reopen)
        else:
            image_qos = dict(IMAGE_QOS, reliability=qos.RELIABLE if p['image_reliable']
                             else qos.BEST_EFFORT)
            self.create_subscription(Image, 'image', self._on_image, QoSProfile(**image_qos))
        self.create_timer(float(p['status_period']), self._publish_diagnostics)
        self.get_logger().info(
            f'tracking {len(robots)} robots from '
            f'{p["source"] or self.resolve_topic_name("image")} '
            f'(calibration {p["calibration_file"]}, residual {calibration.rms_m * 1000:.1f} mm; '
            + (f'lens k1 {calibration.lens.k1:.4f} k2 {calibration.lens.k2:.4f}; '
               if calibration.lens is not None else 'no lens distortion; ')
            + ('measured colours)' if calibration.cover_colors is not None
               else "the fleet file's colours)"))

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    # -- inputs ------------------------------------------------------------------------
    def _on_image(self, msg: Image) -> None:
        try:
            image = image_from_msg(msg)
        except ImageError as exc:
            self._report(f'unreadable frame on {self.resolve_topic_name("image")}: {exc}')
            self.counts['bad_frames'] += 1
            return
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        self._process(image, stamp if stamp > 0 else self._now(), msg.header.stamp)

    def _open(self) -> None:
        import cv2
        source = self.params['source']
        device = int(source) if str(source).isdigit() else source
        capture = cv2.VideoCapture(device)
        if capture.isOpened():
            self._capture = capture
            self._clear(f'camera {source} open')
        else:
            capture.release()
            self._report(f'cannot open camera {source}: check the device or file path '
                         f'(retrying every {self.params["reopen_period"]} s)')

    def _reopen(self) -> None:
        if self._capture is None:
            self._open()

    def _on_capture_timer(self) -> None:
        if self._capture is None:
            return
        ok, image = self._capture.read()
        if not ok or image is None:
            self.counts['bad_frames'] += 1
            self._capture.release()
            self._capture = None
            self._report(f'camera {self.params["source"]}: no frame (unplugged, or the end of '
                         f'the file); reopening every {self.params["reopen_period"]} s')
            return
        now = self.get_clock().now()
        self._process(image, now.nanoseconds * 1e-9, now.to_msg())

    def _report(self, text: str) -> None:
        """Log a problem once, until it clears."""
        if text != self._problem:
            self.get_logger().warning(text)
            self._problem = text

    def _clear(self, text: str) -> None:
        if self._problem is not None:
            self.get_logger().info(text)
        self._problem = None

    # -- one frame ---------------------------------------------------------------------
    def _process(self, image, seconds: float, stamp) -> None:
        w, h = self.tracker.calibration.size
        if image.shape[1] != w or image.shape[0] != h:
            self.counts['bad_frames'] += 1
            self._report(f'a {image.shape[1]}x{image.shape[0]} frame, but calibration_file '
                         f'is for {w}x{h}: run camera_calibrate at this resolution')
            return
        result = self.tracker.update(image, seconds)
        self.counts['frames'] += 1
        for key in ('unknown_covers', 'ambiguous', 'incomplete'):
            self.counts[key] += getattr(result, key)
        if self._problem is not None:
            self._clear('frames readable again')
        for k, (x, y, yaw) in result.poses.items():
            self._pose_pubs[k].publish(pose_stamped(x, y, yaw, stamp))
        missing = set(result.missing)
        for k in sorted(missing - self._missing):
            self.get_logger().warning(f'agent {k} missing: not seen for '
                                      f'{self.params["missing_timeout"]} s')
        for k in sorted(self._missing - missing):
            self.get_logger().info(f'agent {k} seen again')
        self._missing = missing
        if self._annotated is not None and self._annotated.get_subscription_count() > 0:
            self._annotated.publish(image_to_msg(
                annotate(image, result, self.tracker.calibration, self.radius), stamp))

    def _publish_diagnostics(self) -> None:
        array = DiagnosticArray()
        array.header.stamp = self.get_clock().now().to_msg()
        for k in sorted(self._pose_pubs):
            st = DiagnosticStatus(name=f'camera_tracker: agent_{k}', hardware_id=f'agent_{k}')
            if k in self._missing:
                st.level, st.message = DiagnosticStatus.ERROR, 'missing'
            else:
                st.level, st.message = DiagnosticStatus.OK, 'tracked'
            array.status.append(st)
        st = DiagnosticStatus(name='camera_tracker: camera', level=DiagnosticStatus.OK,
                              message=self._problem or 'ok')
        if self._problem is not None:
            st.level = DiagnosticStatus.ERROR
        st.values = [KeyValue(key=k, value=str(v)) for k, v in sorted(self.counts.items())]
        array.status.append(st)
        self._diag.publish(array)

    def close(self) -> None:
        """Release the camera."""
        if self._capture is not None:
            self._capture.release()
            self._capture = None


def main(args: list[str] | None = None) -> None:
    """Run camera_tracker_node until interrupted."""
    run_node(CameraTrackerNode, 'camera_tracker_node', args, stop=CameraTrackerNode.close)


if __name__ == '__main__':
    os.environ.setdefault('PYTHONUNBUFFERED', '1')
    sys.exit(main())
