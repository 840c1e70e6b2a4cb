"""swarm_sim.run_record: records written as the run goes, read back whole or cut."""

import json
import logging
import math

import numpy as np
import pytest

from swarm_sim.run_record import (
    read_record_log,
    read_truth_csv,
    RecordError,
    RecordLog,
    RunRecord,
)
from swarm_sim.world_model import TruthSample

DTYPES = {'times': 'float64', 'positions': 'float64', 'alive': 'bool', 'digests': 'int64',
          'min_separation': 'float64'}


def row(k: int) -> dict:
    return {'times': 0.5 * k, 'positions': np.array([[k + 0.123456, -1.0], [np.nan, 2.0]]),
            'alive': np.array([True, k % 2 == 0]),
            'digests': np.array([2**62 + k, -3], dtype=np.int64),
            'min_separation': math.inf if k == 0 else 1.5}


def write_log(path, rows: int, flush_period_s: float = 1e-6, end: bool = True):
    log = RecordLog(path, {'seed': 7, 'dtypes': DTYPES}, flush_period_s)
    for k in range(rows):
        log.add(row(k))
    if end:
        log.close({'metrics': {'settled': True}})
    return log


def test_a_closed_log_reads_back_every_row_with_its_types(tmp_path, caplog):
    write_log(tmp_path / 'r.jsonl', 5)
    with caplog.at_level(logging.WARNING):
        run = read_record_log(tmp_path / 'r.jsonl')
    assert not run.cut and run.rows == 5 and not caplog.records
    assert run.header['seed'] == 7 and run.end == {'metrics': {'settled': True}}
    rec = run.record
    assert rec['times'].tolist() == [0.0, 0.5, 1.0, 1.5, 2.0]
    assert rec['positions'].shape == (5, 2, 2)
    assert rec['positions'][3, 0, 0] == pytest.approx(3.1235)      # rounded to 0.1 mm
    assert np.isnan(rec['positions'][:, 1, 0]).all()
    assert rec['alive'].dtype == bool and rec['alive'][:, 1].tolist() == [
        True, False, True, False, True]
    assert rec['digests'][4, 0] == 2**62 + 4                        # int64 kept exact
    assert rec['min_separation'][0] == math.inf
    assert (np.diff(rec['wall']) >= 0).all()


def test_a_log_cut_mid_line_gives_the_rows_before_and_one_warning_line(tmp_path, caplog):
    """A writer killed mid-write leaves a partial last line and no end line."""
    path = tmp_path / 'r.jsonl'
    log = write_log(path, 4, end=False)
    log._file.close()
    with open(path, 'a', encoding='utf-8') as f:
        f.write('{"row": {"times": 2.0, "posit')
    with caplog.at_level(logging.WARNING):
        run = read_record_log(path)
    assert run.cut and run.rows == 4 and run.end is None
    assert run.record['times'][-1] == 1.5
    assert len(caplog.records) == 1
    line = caplog.records[0].getMessage()
    assert 'was cut' in line and '4 samples up to t=1.5 s' in line and 'partial' in line


def test_rows_reach_the_file_when_the_flush_period_has_passed(tmp_path):
    """With an hour's flush period the rows stay in the writer's buffer; with a period
    already passed at every write each row is on disk when add returns."""
    slow = write_log(tmp_path / 'slow.jsonl', 3, flush_period_s=3600.0, end=False)
    on_disk = (tmp_path / 'slow.jsonl').read_text().splitlines()
    assert len(on_disk) == 1 and 'header' in on_disk[0]
    slow.close()
    fast = write_log(tmp_path / 'fast.jsonl', 3, end=False)
    assert len((tmp_path / 'fast.jsonl').read_text().splitlines()) == 4
    fast.close()


def test_an_exception_leaves_the_log_without_its_end_line(tmp_path):
    with pytest.raises(RuntimeError), RecordLog(tmp_path / 'r.jsonl', {}) as log:
        log.add(row(0))
        raise RuntimeError('the trial failed')
    assert read_record_log(tmp_path / 'r.jsonl').cut


@pytest.mark.parametrize('text, says', [
    ('', 'no header line'), ('{"row": {}}\n', 'no header line'),
    ('{"header": {}}\nnot json\n', 'line 2 is not JSON'),
    ('{"header": {}}\n{"row": {"a": 1}}\n{"row": {"b": 1}}\n', 'do not hold the same'),
])
def test_an_unreadable_log_is_one_line(tmp_path, text, says):
    (tmp_path / 'r.jsonl').write_text(text)
    with pytest.raises(RecordError, match=says):
        read_record_log(tmp_path / 'r.jsonl')
    with pytest.raises(RecordError, match='cannot read'):
        read_record_log(tmp_path / 'missing.jsonl')


def truth(t: float, n: int = 3) -> TruthSample:
    pos = np.arange(2 * n, dtype=float).reshape(n, 2) + t
    return TruthSample(t=t, positions=pos, velocities=-pos, yaws=np.zeros(n),
                       alive=np.arange(n) != 1,
                       min_separation=2.0)


def test_the_truth_csv_of_a_killed_sim_reads_to_its_last_whole_sample(tmp_path, caplog):
    """sim_node's record: flushed as it goes; without medium.json (written on close) and
    with a partial last sample, the whole samples are read and one line says it was cut."""
    record = RunRecord(str(tmp_path), [4, 5, 6], flush_period_s=1e-6)
    for k in range(3):
        record.add(truth(0.5 * k))
    text = (tmp_path / 'truth.csv').read_text()
    assert text.count('\n') == 1 + 3 * 3          # flushed: on disk before any close
    with open(tmp_path / 'truth.csv', 'a', encoding='utf-8') as f:
        f.write('1.500,4,1.0,2.0,0.0,0.0,1\n1.500,5,3.0')
    with caplog.at_level(logging.WARNING):
        got = read_truth_csv(tmp_path)
    assert got['cut'] and got['times'].tolist() == [0.0, 0.5, 1.0]
    assert got['ids'].tolist() == [4, 5, 6]
    assert got['positions'][2, 1].tolist() == [3.0, 4.0]
    assert got['velocities'][2, 1].tolist() == [-3.0, -4.0]
    assert got['alive'][0].tolist() == [True, False, True]
    assert len(caplog.records) == 1 and '3 samples up to t=1.0 s' in caplog.records[0].getMessage()


def test_a_closed_truth_csv_is_not_cut(tmp_path, caplog):
    record = RunRecord(str(tmp_path), [0, 1])
    record.add(truth(0.0, 2))
    record._csv.close()
    (tmp_path / 'medium.json').write_text(json.dumps({}))
    with caplog.at_level(logging.WARNING):
        got = read_truth_csv(tmp_path)
    assert not got['cut'] and not caplog.records and got['positions'].shape == (1, 2, 2)
