"""A SIGKILLed evaluator leaves its trial's record readable, short of at most the last
flush period (swarm_sim.run_record.RecordLog through swarm_eval.trials)."""

import os
import pathlib
import signal
import subprocess
import sys
import time

import numpy as np

from swarm_sim.run_record import read_record_log

ROOT = pathlib.Path(__file__).resolve().parents[3]
FLUSH_S = 1.0
ROWS_BEFORE_KILL = 20      # samples on disk (10 sim s at 2 Hz) before the kill


def test_a_killed_evaluator_leaves_all_but_the_last_flush_period(tmp_path):
    # A settle hold longer than the run: the trial cannot end before it is killed.
    proc = subprocess.Popen(
        [sys.executable, str(ROOT / 'scripts' / 'evaluate.py'), '--agents', '6',
         '--beacons', '3', '--shape-scale', '0.3', '--duration', '3000', '--settle-hold',
         '5000', '--record-flush', str(FLUSH_S), '--out', str(tmp_path)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    path = tmp_path / 'records' / 'trial_0.jsonl'
    try:
        deadline = time.monotonic() + 90.0
        while time.monotonic() < deadline and proc.poll() is None:
            if path.exists() and path.read_text().count('\n') > ROWS_BEFORE_KILL:
                break
            time.sleep(0.2)
        assert proc.poll() is None, proc.stderr.read().decode()[-2000:]
        assert path.exists(), 'no record after 90 s'
        time.sleep(2.5 * FLUSH_S)       # a few flushes more while the trial runs
        killed_at = time.time()
        os.killpg(proc.pid, signal.SIGKILL)   # the evaluator and its worker process
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    run = read_record_log(path)
    assert run.cut and run.end is None
    assert run.rows > ROWS_BEFORE_KILL
    times = run.record['times']
    assert times[0] <= 0.5 and np.allclose(np.diff(times), 0.5)   # every sample, in order
    assert run.record['positions'].shape == (run.rows, 6, 2)
    # The last row on disk was written at most one flush period (plus one sample's wall
    # time and scheduling slack on a loaded machine) before the kill.
    assert killed_at - run.record['wall'][-1] < FLUSH_S + 1.0
    assert (tmp_path / 'trials.jsonl').read_text() == ''   # no trial finished

