"""The rclpy-free QoS table matches rclpy's enums and builds valid profiles."""

import pytest

rclpy_qos = pytest.importorskip('rclpy.qos')

from swarm_mission import qos  # noqa: E402


def test_integers_match_rclpy_enums():
    assert qos.KEEP_LAST == rclpy_qos.QoSHistoryPolicy.KEEP_LAST.value
    assert qos.RELIABLE == rclpy_qos.QoSReliabilityPolicy.RELIABLE.value
    assert qos.BEST_EFFORT == rclpy_qos.QoSReliabilityPolicy.BEST_EFFORT.value
    assert qos.TRANSIENT_LOCAL == rclpy_qos.QoSDurabilityPolicy.TRANSIENT_LOCAL.value
    assert qos.VOLATILE == rclpy_qos.QoSDurabilityPolicy.VOLATILE.value


@pytest.mark.parametrize('name', ['LATCHED', 'SENSOR', 'IMU', 'RADIO', 'STATE'])
def test_profiles_build(name):
    profile = rclpy_qos.QoSProfile(**getattr(qos, name))
    assert profile.depth >= 1
