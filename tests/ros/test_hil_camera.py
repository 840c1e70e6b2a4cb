"""The hardware-in-the-loop world's true poses rendered by camera_sim_node, through
camera_tracker_node: the tracker's /agent_K/pose matches the boards' true poses
(/truth/agent_K/pose) to within a centimetre and 3 degrees, and the hil_world publishes
neither images nor an /agent_K/pose of its own."""

from __future__ import annotations

import math

import pytest

rclpy = pytest.importorskip('rclpy')

from geometry_msgs.msg import PoseStamped  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile  # noqa: E402
from spin import ros_context, spin_until  # noqa: E402

from swarm_bridge.arena_calibration import calibrate  # noqa: E402
from swarm_bridge.camera_render import CameraRenderer, sim_camera_config  # noqa: E402
from swarm_bridge.camera_sim_node import CameraSimNode  # noqa: E402
from swarm_bridge.camera_sim_node import PARAMETERS as CAMERA  # noqa: E402
from swarm_bridge.camera_tracker_node import CameraTrackerNode  # noqa: E402
from swarm_bridge.hil_world_node import HilWorldNode  # noqa: E402
from swarm_common import qos  # noqa: E402


def _yaw(msg: PoseStamped) -> float:
    return 2.0 * math.atan2(msg.pose.orientation.z, msg.pose.orientation.w)


def test_rendered_camera_and_tracker_give_the_true_poses(tmp_path):
    params = {name: default for name, (default, _) in CAMERA.items()}
    calibrate(CameraRenderer(sim_camera_config(params)).render([])).save(tmp_path / 'cal.yaml')
    poses = [-0.55, -0.55, 0.0, 0.55, -0.55, 90.0, 0.55, 0.55, 180.0, -0.55, 0.55, -90.0,
             0.0, -0.62, 45.0]
    with ros_context() as (context, executor):
        world = HilWorldNode(context=context, parameter_overrides=[
            Parameter('camera', value='image'), Parameter('relay_radio', value=False),
            Parameter('initial_poses', value=poses)])
        camera = CameraSimNode(context=context)
        tracker = CameraTrackerNode(context=context, parameter_overrides=[
            Parameter('calibration_file', value=str(tmp_path / 'cal.yaml'))],
            cli_args=['--ros-args', '-r', 'image:=/camera/image_raw'])
        probe = rclpy.create_node('probe', context=context)
        for node in (world, camera, tracker, probe):
            executor.add_node(node)
        truth, seen = {}, {}
        for k in world.boards:
            probe.create_subscription(PoseStamped, f'/truth/agent_{k}/pose',
                                      lambda m, k=k: truth.__setitem__(k, m),
                                      QoSProfile(**qos.SENSOR))
            probe.create_subscription(PoseStamped, f'/agent_{k}/pose',
                                      lambda m, k=k: seen.__setitem__(k, m),
                                      QoSProfile(**qos.SENSOR))
        try:
            assert spin_until(executor, lambda: len(seen) == len(world.boards)
                              and len(truth) == len(world.boards), 30.0), sorted(seen)
            for k, msg in seen.items():
                true = truth[k]
                assert msg.header.frame_id == 'map'
                err = math.hypot(msg.pose.position.x - true.pose.position.x,
                                 msg.pose.position.y - true.pose.position.y)
                assert err < 0.01, (k, err)
                turn = math.degrees(math.remainder(_yaw(msg) - _yaw(true), math.tau))
                assert abs(turn) < 3.0, (k, turn)
            def published(node: str) -> set[str]:
                if (node, '/') not in world.get_node_names_and_namespaces():
                    return set()                              # not discovered yet
                return {name for name, _ in
                        world.get_publisher_names_and_types_by_node(node, '/')}

            # The images come from the camera node (hil_camera), the poses from the
            # tracker: the world publishes neither.
            assert spin_until(executor, lambda: '/camera/image_raw' in published('hil_camera'))
            world_topics = published('hil_world')
            assert '/camera/image_raw' not in world_topics
            assert not any(t.endswith('/pose') and t.startswith('/agent_') for t in world_topics)
        finally:
            tracker.close()
            world.close()
            for node in (world, camera, tracker, probe):
                node.destroy_node()
