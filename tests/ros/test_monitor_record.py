"""The monitor's record streamed to a RecordLog: the node holds no sample while the run
goes, and the record read back at the end is the one it would have kept in memory."""

from __future__ import annotations

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from spin import ros_context  # noqa: E402

from swarm_bringup.monitor_node import MonitorNode, RECORD_DTYPES  # noqa: E402
from swarm_msgs.msg import AgentState, AgentTruth, SwarmTruth  # noqa: E402
from swarm_sim.run_record import RecordLog  # noqa: E402


def _feed(monitor: MonitorNode, samples: int) -> None:
    rng = np.random.default_rng(0)
    for k in range(samples):
        t = 0.5 * k
        for agent in (0, 1, 2):
            state = AgentState(id=agent, mode=1, assigned_goal=agent + 10,
                               assignment_digest=2**40 + agent, assignment_round=k // 4,
                               localized=k > 3)
            state.position = [float(v) for v in rng.normal(size=2)]
            monitor._on_state(state)
        truth = SwarmTruth()
        truth.header.stamp.sec, truth.header.stamp.nanosec = int(t), int(t % 1 * 1e9)
        truth.agents = [AgentTruth(id=a, position=[float(v) for v in rng.normal(size=2)],
                                   velocity=[0.1 * a, 0.0], alive=a != 2 or k < 5)
                        for a in (0, 1, 2)]
        monitor._on_truth(truth)


def test_a_streamed_record_is_held_on_disk_and_reads_back_as_kept_in_memory(tmp_path):
    with ros_context() as (context, _):
        in_memory = MonitorNode([0, 1, 2], context=context)
        log = RecordLog(tmp_path / 'monitor.jsonl', {'dtypes': RECORD_DTYPES})
        streamed = MonitorNode([0, 1, 2], context=context, record_log=log)
        try:
            _feed(in_memory, 40)
            _feed(streamed, 40)
            assert not any(streamed._rows.values())        # nothing held by the node
            assert log.rows == 40
            kept, read = in_memory.record(), streamed.record()
        finally:
            in_memory.destroy_node()
            streamed.destroy_node()
    assert set(read) == set(kept) == set(RECORD_DTYPES)
    for key in RECORD_DTYPES:
        assert read[key].dtype == kept[key].dtype and read[key].shape == kept[key].shape, key
        if kept[key].dtype.kind == 'f':   # a RecordLog keeps floats to 0.1 mm
            np.testing.assert_allclose(read[key], kept[key], atol=5e-5, err_msg=key)
        else:
            np.testing.assert_array_equal(read[key], kept[key], err_msg=key)
    assert read['digests'][0, 0] == 2**40 and not read['alive'][-1, 2]
