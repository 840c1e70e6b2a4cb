"""swarm_eval.measured: the Measured page rendered from the runs' files, never typed.

The fixtures are the files the studies write (the keys their code writes, figures chosen
so that each rendered number can be checked by hand); a row without files is "not
measured" next to its command.
"""

from __future__ import annotations

import json
import pathlib
import sys

import pytest

from swarm_eval import measured
from swarm_eval.measured import NOT_MEASURED, ROWS, RUNS


def _write(path: pathlib.Path, name: str, payload) -> pathlib.Path:
    path.mkdir(parents=True, exist_ok=True)
    text = payload if isinstance(payload, str) else json.dumps(payload)
    (path / name).write_text(text, encoding='utf-8')
    return path


def _table(page: str) -> list[list[str]]:
    """The cells of the page's table rows (header and rule excluded)."""
    lines = [ln for ln in page.splitlines() if ln.startswith('| ')]
    return [[c.strip() for c in ln.strip('|').split(' | ')] for ln in lines[1:]]


def _study_row(shape: str, disp: float, settle: float, sep: float, loc: float, p95: float,
               status: str = 'settled', method: str = 'bubble') -> dict:
    return {'shape': shape, 'method': method, 'status': status, 'note': '',
            'displacement_ratio': disp, 'settling_ratio': settle, 'min_separation_ratio': sep,
            'max_localization_error': loc, 'contacts': 0, 'assignment_agreement': 0.9,
            'metrics': {'settle_hold_s': 30.0, 'p95_localization_error': p95}}


def test_the_table_has_one_row_per_declared_row_and_says_not_measured_without_files(tmp_path):
    page = measured.render(tmp_path)
    cells = _table(page)
    assert [c[0] for c in cells] == [row.what for row in ROWS]
    assert all(c[2] == NOT_MEASURED for c in cells)
    # every command is on the page, with the run's directory in place of {out}
    for row, (_, command, _) in zip(ROWS, cells):
        for run in row.runs:
            assert '{out}' not in command
            if '{out}' in run.argv:
                assert str(tmp_path / run.name) in command
    # one provenance line per run, each "not measured"
    assert page.count(f': {NOT_MEASURED}\n') == len(RUNS)


def test_a_shape_study_renders_its_medians_worsts_and_targets(tmp_path):
    rows = [_study_row('blob_1', 1.02, 1.2, 1.30, 1.2, 0.5),
            _study_row('neck_1', 1.04, 1.4, 1.10, 1.8, 0.7),
            _study_row('holes_1', 1.08, 2.0, 1.20, 2.6, 0.9, status='not settled')]
    _write(tmp_path / 'shapes30_seed100', 'study.json',
           {'arguments': {'shapes': 3, 'seed': 100}, 'rows': rows})
    cell = _table(measured.render(tmp_path))[0][2]
    seed100, seed200 = cell.split('<br>')
    assert seed100.startswith('3 shapes, seed 100: 2 of 3 settled and held 30 s;')
    # medians of (1.02, 1.04, 1.08), (1.2, 1.4, 2.0), (0.5, 0.7, 0.9), (1.2, 1.8, 2.6)
    assert 'displacement / bound median 1.040, worst 1.080 (targets 1.05 / 1.10: met)' in seed100
    assert 'settling / least settling median 1.40, worst 2.00' in seed100
    assert 'minimum separation 1.10, 0 contacts' in seed100
    assert 'p95 median 0.70 m, maximum median 1.80 m, worst 2.60 m, under 1.5 m on 1 of 3' \
        in seed100
    assert seed100.endswith('; holes_1 not settled')
    assert seed200 == NOT_MEASURED


def test_a_missed_displacement_target_is_said(tmp_path):
    rows = [_study_row('a', 1.06, 1.0, 1.0, 1.0, 0.5), _study_row('b', 1.07, 1.0, 1.0, 1.0, 0.5)]
    path = _write(tmp_path, 'study.json', {'rows': rows})
    assert '(targets 1.05 / 1.10: missed)' in measured.shape_study_result(path)


def test_the_ros_subset_renders_ranges_and_the_median_per_mode(tmp_path):
    rows = [_study_row('blob_1', 1.02, 1.2, 1.3, 1.0, 0.5),      # headless: not in the cell
            _study_row('blob_1', 1.03, 1.1, 1.2, 1.5, 0.5, method='bubble/ros-composed'),
            _study_row('blob_1', 1.05, 1.3, 1.1, 2.0, 0.5, method='bubble/ros-per-process'),
            _study_row('neck_1', 1.01, 2.5, 1.4, 1.1, 0.5, method='bubble/ros-composed'),
            _study_row('neck_1', 1.04, 1.5, 1.0, 1.2, 0.5, method='bubble/ros-per-process')]
    path = _write(tmp_path, 'study.json', {'arguments': {'ros_agents': 16, 'ros_beacons': 4},
                                           'rows': rows})
    cell = measured.ros_subset_result(path)
    assert cell.startswith('16 agents, 4 beacons; 4 of 4 runs settled and held 30 s '
                           '(2 shapes x 2 modes)')
    assert 'settling 1.10-2.50 x the least settling time (median 1.80 composed, 1.40 per ' \
        'process)' in cell
    assert 'displacement 1.010-1.050 x the bound; minimum separation 1.00-1.40' in cell
    assert 'maximum localization error after the first fix 1.10-2.00 m' in cell
    headless_only = _write(tmp_path / 'h', 'study.json', {'rows': rows[:1]})
    with pytest.raises(measured.OutputError, match='no ROS rows'):
        measured.ros_subset_result(headless_only)


def test_the_thesis_scenario_renders_each_trial(tmp_path):
    trial = {'settled': True, 'settling_time': 150.0, 'settling_ratio': 1.5,
             'least_settling_time': 100.0, 'redepartures': 2, 'total_displacement': 1020.0,
             'displacement_lower_bound': 1000.0, 'min_separation_ratio': 1.2, 'contacts': 0,
             'assignment_agreement': 0.98, 'duplicate_goal_claims_final': 0,
             'duplicate_goal_claims_peak': 4, 'duplicate_goal_claims_integral': 30.0,
             'p95_localization_error': 0.5, 'rms_localization_error': 0.3,
             'max_localization_error': 4.0, 'seed': 0}
    other = dict(trial, settled=False, settling_time=None, seed=1)
    _write(tmp_path / 'thesis', 'metrics.json', {'trials': [trial, other]})
    thesis = next(r for r in ROWS if r.key == 'thesis')
    cell = {c[0]: c[2] for c in _table(measured.render(tmp_path))}[thesis.what]
    assert cell.startswith('seeds 0, 1: 1 of 2 settled and held: 150.0 / - s, 1.50 / 1.50')
    assert 'displacement 1.020 / 1.020 x the bound' in cell
    assert 'goals claimed twice: 0 at the end, up to 4 / 4 at once' in cell


def test_the_localization_row_renders_per_period_and_noise(tmp_path):
    periods = {k: {'max_error': m, 'p95_error': 0.5, 'rms_error': r, 'steady_max_error': s}
               for k, m, r, s in (('3', 4.84, 0.30, 1.72), ('5', 2.17, 0.31, 1.79))}
    _write(tmp_path / 'localization_toa', 'summary.json',
           {'seeds': 3, 'duration_s': 200.0, 'periods': periods,
            'thesis_max_error_m': {'3': 3.0, '5': 10.0}})
    row = next(r for r in ROWS if r.key == 'localization')
    cell = measured.result_cell(row, {run.name: tmp_path / run.name for run in row.runs})
    thesis, toa = cell.split('<br>')
    assert thesis == f'thesis noise (2 m on the fix): {NOT_MEASURED}'
    assert toa == ("the system's TOA ranges: periods 3 / 5 s, 3 seeds x 200 s: max 4.8 / 2.2 m "
                   '(1.7-1.8 m for agents NORMAL three periods), p95 0.50 / 0.50 m, RMS '
                   '0.30-0.31 m (thesis: below 3 / 10 m)')


def test_dsdv_faults_hil_and_mesh_render_from_their_files(tmp_path):
    table = [{'agents': 50, 'loss': loss, 'seeds': 5, 'link_break_mean_periods': mean,
              'link_break_worst_periods': worst, 'link_break_not_converged': missed,
              'routing_bytes_per_s_per_agent': traffic}
             for loss, mean, worst, missed, traffic in ((0.0, 2.4, 2.75, 0, 193.0),
                                                        (0.3, 6.0, None, 1, 204.0),
                                                        (0.5, None, None, 5, 210.0))]
    dsdv = measured.dsdv_result(_write(tmp_path / 'd', 'bench_dsdv.json',
                                       {'period_s': 2.0, 'table': table}))
    assert dsdv == ('loss 0 / 30 / 50 %, periods (2 s) to converge after a link break, mean '
                    '(worst): 50 agents 2.4 (2.75) / 6.0, 1 of 5 not converged / none of 5 '
                    'converged; routing traffic per agent 193-210 B/s at 50 agents')
    trials = [{'case': 'kill_30', 'kind': 'kill', 'value': 0.3, 'agents': 6, 'agents_alive': 4,
               'settled': True, 'passed': True},
              {'case': 'beacons_one', 'kind': 'beacons', 'value': 1, 'agents': 6,
               'agents_alive': 5, 'settled': True, 'passed': False}]
    faults = measured.fault_result(_write(
        tmp_path / 'f', 'faults.json', {'config': {'agents': 6}, 'trials': trials, 'cases': {
            'kill_30': {'recovery_time': 19.06}, 'beacons_one': {'recovery_time': 15.6}}}))
    assert faults == ('6 agents: 2 of 2 trials settled, 1 passed; recovery after the fault: '
                      'kill_30 19.1 s (2 of 6 agents killed), beacons_one 15.6 s (1 beacon '
                      'removed)')
    hil = measured.hil_result(_write(tmp_path / 'h', 'hil.json', {'results': [
        {'shape': 'hw_square', 'settling_time': 38.6, 'final_goal_error': [0.012, 0.0197],
         'total_displacement': 4.0757, 'displacement_lower_bound': 3.6653}]}))
    assert hil == ('hw_square settled at 38.6 s, every robot within 2.0 cm of its goal '
                   '(displacement 4.08 m, bound 3.67 m)')
    arrived = measured.hil_result(_write(tmp_path / 'a', 'hil.json', {'results': [
        {'shape': 'hw_line', 'settling_time': 60.2, 'arrival_time': 66.5,
         'final_goal_error': [0.019], 'total_displacement': 6.17,
         'displacement_lower_bound': 5.5}, {'shape': 'hw_arrow', 'settling_time': 30.0,
                                            'arrival_time': None, 'final_goal_error': [0.2],
                                            'total_displacement': 3.3,
                                            'displacement_lower_bound': 3.0}]}))
    assert arrived == ('hw_line settled at 60.2 s, arrived at 66.5 s, every robot within 1.9 '
                       'cm of its goal (displacement 6.17 m, bound 5.50 m); hw_arrow settled '
                       'at 30.0 s, not arrived, every robot within 20.0 cm of its goal '
                       '(displacement 3.30 m, bound 3.00 m)')
    stats = {'epsilon_t': {'mean': 0.40, 'max': 0.48}, 'epsilon_g': {'mean': 0.033,
                                                                    'max': 0.033}}
    fractal = {'epsilon_t': {'mean': 0.9, 'max': 1.0}, 'epsilon_g': {'mean': 0.12, 'max': 0.2}}
    mesh = measured.mesh_result(_write(tmp_path / 'm', 'mesh_study.json', {
        'circle_314': {'bubble': dict(stats, runs=20), 'fractal': fractal}}))
    assert mesh == ('20 seeds; bubble packing eps_t / eps_g, mean (worst seed): circle_314 '
                    '0.40 (0.48) / 0.033; fractals 0.90 / 0.12')


def test_commands_reporting_on_stdout_render_from_the_saved_output(tmp_path):
    crlb = _write(tmp_path / 'crlb', 'pytest.txt',
                  '.\nRMS error / sqrt(CRLB) = 1.002 +/- 0.0079 (n=4000, sigma=0.3 m, '
                  '5 beacons)\n1 passed in 2.31s\n')
    assert measured.crlb_result(crlb) == ('RMS error / sqrt(CRLB) = 1.002 over 4000 fixes '
                                          '(accepted: 1 +/- 4 standard errors, 0.032); 1 '
                                          'passed in 2.31s')
    e2e = _write(tmp_path / 'e2e', 'pytest.txt',
                 '== 8 passed, 1 failed in 81.20s (0:01:21) ==\n')
    assert measured.pytest_summary(e2e) == '8 passed, 1 failed in 81.20s (0:01:21)'
    fw = _write(tmp_path / 'fw', 'make.txt', 'flash: 3576 of 4096 words (87.3 %)\n'
                'RAM:   242 of 256 bytes (94.5 %; general purpose registers only)\n')
    assert measured.firmware_result(fw).startswith('3576 / 4096 flash words, 242 / 256 RAM')


def test_unreadable_files_say_so_instead_of_a_figure(tmp_path):
    _write(tmp_path / 'faults', 'faults.json', '{"cases": ')
    _write(tmp_path / 'crlb', 'pytest.txt', 'E   assert False\n1 failed in 2.0s\n')
    cells = {c[0]: c[2] for c in _table(measured.render(tmp_path))}
    faults = cells[next(r.what for r in ROWS if r.key == 'faults')]
    crlb = cells[next(r.what for r in ROWS if r.key == 'crlb')]
    assert faults.startswith(f'{NOT_MEASURED}: files unreadable (OutputError:')
    assert crlb.startswith(f'{NOT_MEASURED}: files unreadable') and 'CRLB' in crlb


def test_a_run_record_gives_the_command_and_provenance(tmp_path):
    run = RUNS['faults']
    path = _write(tmp_path / 'faults', 'faults.json', {'cases': {}})
    argv = [*measured.command(run.argv, path), '--seeds', '2']
    changed = [' M ros2_ws/src/swarm_sim/swarm_sim/world.py', ' M README.md']
    _write(path, measured.RECORD, {'argv': argv, 'commit': 'abcdef1234567890', 'dirty': changed,
                                   'started': '2026-12-03T14:00:00+00:00', 'wall_s': 41.5,
                                   'returncode': 0, 'cores': 2, 'python': '3.11.7'})
    assert measured.shown_command(run, path).endswith('--seeds 2')
    assert measured.provenance(run, path).startswith(
        '`faults`: commit `abcdef123456` with uncommitted changes to 2 files (measure.json '
        'names them), 2026-12-03T14:00:00+00:00, 41.5 s wall, exit 0, 2 cores, Python 3.11.7')


def test_run_runs_a_command_once_and_records_it(tmp_path, capsys):
    script = 'import sys; open(sys.argv[1] + "/out.json", "w").write("{}"); print("hello")'
    run = measured.Run('echo', (sys.executable, '-c', script, '{out}'), ('out.json',),
                       lambda path: 'read')
    row = measured.Row('echo', 'an echo', (run,))
    assert measured.run_rows([row], tmp_path) == 0
    record = json.loads((tmp_path / 'echo' / measured.RECORD).read_text())
    assert record['argv'][-1] == str((tmp_path / 'echo').resolve())
    assert record['returncode'] == 0 and record['cores'] >= 1
    assert len(record['commit']) == 40 and isinstance(record['dirty'], list)
    assert 'hello' in (tmp_path / 'echo' / 'measure.log').read_text()
    assert measured.run_rows([row], tmp_path) == 0        # files there: skipped
    assert 'skipped' in capsys.readouterr().out


@pytest.mark.parametrize('argv, message', [
    (['run', '--out', 'x', '--rows', 'nope'], '--rows nope: unknown row'),
    (['run', '--out', 'x', '--extra', 'mesh'], "--extra 'mesh': give RUN=VALUE"),
    (['render', 'no/such/dir'], 'results directory no/such/dir does not exist'),
])
def test_bad_input_is_one_line_and_exit_2(argv, message, capsys):
    assert measured.main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f'measure: {message}') and err.count('\n') == 1
