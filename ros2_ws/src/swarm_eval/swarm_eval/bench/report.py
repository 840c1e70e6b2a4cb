"""The benchmark suite's targets (issues 6 and 9) and its markdown report."""

from __future__ import annotations

from collections.abc import Callable, Sequence
import pathlib
import shlex

from swarm_eval.bench.common import (
    EVAL_TARGET_PER_MIN,
    ISSUE23,
    ROS_TARGETS,
    ROUND_TARGET_S,
    TARGET_SIZE,
    WORLD_TARGET,
)


def at_size(rows: Sequence[dict], n: int) -> dict | None:
    return next((r for r in rows if r.get('agents') == n), None)


def targets(results: dict) -> list[dict]:
    """The issue's targets, each met (True), missed (False) or not measured (None)."""
    out = []

    def add(name: str, value: float | None, op: str, bound: float, unit: str,
            note: str = '') -> None:
        met = None if value is None else (value < bound if op == '<' else value >= bound)
        out.append({'target': name, 'value': value, 'op': op, 'bound': bound, 'unit': unit,
                    'met': met, 'note': note})

    s = results['sections']
    big = at_size(s.get('assignment', []), TARGET_SIZE)
    add(f'assignment, {TARGET_SIZE} agents (all types), per round',
        big and big['assign_all_s'], '<', ROUND_TARGET_S, 's')
    big = at_size(s.get('cost_rows', []), TARGET_SIZE)
    add(f'cost row, {TARGET_SIZE} agents, one agent per round (worst agent, first round '
        'after new goals)', big and big['row_worst_first_s'], '<', ROUND_TARGET_S, 's',
        'each agent computes only its own row')
    add(f'cost rows, {TARGET_SIZE} agents, every agent in one process per round',
        big and big['all_rows_s'], '<', ROUND_TARGET_S, 's',
        'what the headless evaluator pays; not a stated target of each agent')
    world = at_size(s.get('world', []), WORLD_TARGET[0])
    add(f'pybullet world (issue 6), {WORLD_TARGET[0]} robots on rough terrain, real-time '
        'factor', world and world['real_time_factor'], '>=', WORLD_TARGET[1], 'x',
        f'at {world["physics_hz"]:g} Hz physics, state read every step' if world else '')
    ev = s.get('evaluator')
    value = ev['trials_per_min_all_cores'] if ev and ev['agents'] == 50 else None
    add('evaluator, 50-agent thesis scenario, trials per minute (all cores)', value, '>=',
        EVAL_TARGET_PER_MIN, 'trials/min',
        f'trials bounded to {ev["duration_bound_s"]:g} sim-s; a full trial runs until '
        'settled, so it is slower' if ev else '')
    tp = s.get('throughput')
    command = tp and tp['issue_command']
    # Only the command as the issue gives it counts (not --issue-trials 5, not --quick's).
    exact = command and (command['agents'], command['trials'], command['workers'],
                         command['duration_bound_s']) == (
        ISSUE23['agents'], ISSUE23['trials'], ISSUE23['workers'], None)
    add("issue 23's command (50 agents, 20 trials to their end, 2 workers), trials per "
        'minute, start-up included', command['trials_per_min'] if exact else None, '>=',
        ISSUE23['trials_per_min'], 'trials/min',
        f'{command["settled"]} of {command["trials"]} settled' if command else '')
    large = tp and tp['large_swarm']
    big = large and large['agents'] == ISSUE23['large_agents']    # not --large-agents 50
    add(f'{ISSUE23["large_agents"]} agents headless (issue 23), real-time factor',
        large['real_time_factor'] if big else None, '>=', ISSUE23['large_rtf'], 'x',
        f'the first {large["duration_bound_s"]:g} simulated seconds' if large else '')
    ros = s.get('ros') or []
    for issue, (mode, n, rtf) in [*(('9', t) for t in ROS_TARGETS),
                                  *(('23', t) for t in ISSUE23['ros'])]:
        row = next((r for r in ros if r['mode'] == mode and r['agents'] == n), None)
        add(f'ROS, {n} agents {mode} (issue {issue}), real-time factor once started',
            row and row.get('steady_real_time_factor'), '>=', rtf, 'x',
            (f'whole run with start-up: {fmt_num(row.get("real_time_factor"))}'
             if row else 'run with --ros'))
    if results['config']['quick']:
        for t in out:
            t.update(met=None, note='--quick: figures not representative')
    return out


# ---------------------------------------------------------------------------- report
def fmt_s(value: float | None) -> str:
    """Seconds with a unit that keeps three significant digits."""
    if value is None:
        return 'n/a'
    if value < 1e-3:
        return f'{value * 1e6:.3g} us'
    if value < 1.0:
        return f'{value * 1e3:.3g} ms'
    return f'{value:.3g} s'


def fmt_num(value: float | None, digits: int = 2) -> str:
    return 'n/a' if value is None else f'{value:.{digits}f}'


def scaling_table(results: dict) -> list[str]:
    s = results['sections']
    sizes = results['config']['sizes']

    def cells(rows: list[dict] | None, fn: Callable[[dict], str]) -> list[str]:
        return [fn(r) if (r := at_size(rows or [], n)) else '-' for n in sizes]

    def dsdv(key: str) -> Callable[[dict], str]:
        return lambda r: ('not converged' if r[key] is None else
                          f'{r[key]:.2f} s ({r[key[:-2] + "_periods"]:.2f} periods)')

    def part(method: str) -> list[str]:
        rows = [r for r in s.get('partition', []) if r['method'] == method]
        return cells(rows, lambda r: fmt_s(r['seconds_median']))

    def timed(section: str, key: str) -> list[str]:
        return cells(s.get(section), lambda r: fmt_s(r[key]))

    table = [
        ('DSDV convergence after a link break (simulated time)', 'dsdv',
         cells(s.get('dsdv'), dsdv('link_break_s'))),
        ('DSDV cold start to all shortest routes (simulated time)', 'dsdv',
         cells(s.get('dsdv'), dsdv('cold_start_s'))),
        ('DSDV routing traffic per agent (payload)', 'dsdv',
         cells(s.get('dsdv'), lambda r: f'{r["routing_bytes_per_s_per_agent"]:.0f} B/s')),
        ('Trilateration: localization round of every agent', 'trilateration',
         timed('trilateration', 'round_s')),
        ('Partition: bubble packing', 'partition', part('bubble')),
        ('Partition: randomized fractals', 'partition', part('fractal')),
        ('Visibility graph build (one type, shape change)', 'cost_rows',
         timed('cost_rows', 'graph_build_s')),
        ('Cost row of one agent (median agent, steady round)', 'cost_rows',
         timed('cost_rows', 'row_median_s')),
        ('Cost row of one agent (worst agent, first round after new goals)', 'cost_rows',
         timed('cost_rows', 'row_worst_first_s')),
        ('Cost rows of every agent (one process, steady round)', 'cost_rows',
         timed('cost_rows', 'all_rows_s')),
        ('Hungarian assignment over every row (all types)', 'assignment',
         timed('assignment', 'assign_all_s')),
        ('Hungarian assignment of one type (what one agent solves)', 'assignment',
         timed('assignment', 'assign_one_type_s')),
        ('Radio medium: links (range + line of sight)', 'medium',
         timed('medium', 'links_s')),
        ('Radio medium: one broadcast per agent sent and delivered', 'medium',
         timed('medium', 'transmit_deliver_s')),
    ]
    lines = ['| Algorithm | ' + ' | '.join(f'{n} agents' for n in sizes) + ' |',
             '|---|' + '---|' * len(sizes)]
    lines += [f'| {label} | ' + ' | '.join(values) + ' |'
              for label, section, values in table if section in s]
    return lines


def executor_paragraph(ex: dict) -> list[str]:
    """The executor table and the 'what we chose and why' paragraph, from the numbers."""
    single, events = ex['executors'].get('single'), ex['executors'].get('events')
    lines = ['| Executor | callbacks/s | timer rate achieved [Hz] | CPU cores | '
             'cores per 1000 callbacks/s |', '|---|---|---|---|---|']
    for kind, r in ex['executors'].items():
        lines.append(f'| {kind} | {r["callbacks_per_s"]:.0f} | '
                     f'{r["timer_rate_achieved"]:.1f} | {r["cpu_cores"]:.2f} | '
                     f'{r["cores_per_1000_cb_s"]:.3f} |')
    lines.append('')
    chosen = ex.get('composed_node_default', 'unknown')
    text = (f'**What we chose and why.** `composed_node` spins its agents with '
            f'`agent_node.make_executor()`, which gives a `{chosen}` unless '
            '`SWARM_EXECUTOR=events` is set.')
    if not (single and events):
        return lines + [text]
    ratio = single['cores_per_1000_cb_s'] / max(events['cores_per_1000_cb_s'], 1e-9)
    events_cheaper = ratio > 1
    change = abs(1.0 - 1.0 / ratio) * 100
    text += (f' Measured here, the EventsExecutor needs {change:.0f} % '
             f'{"less" if events_cheaper else "more"} CPU per callback than the '
             f'SingleThreadedExecutor ({events["cores_per_1000_cb_s"]:.3f} vs '
             f'{single["cores_per_1000_cb_s"]:.3f} cores per 1000 callbacks/s).')
    for kind, r in (('SingleThreadedExecutor', single), ('EventsExecutor', events)):
        if r['timer_rate_achieved'] < 0.95 * ex['rate_hz']:
            text += (f' The {kind} fell behind: its timers fired at '
                     f'{r["timer_rate_achieved"]:.1f} of {ex["rate_hz"]:g} Hz with '
                     f'{r["cpu_cores"]:.2f} cores busy.')
    check = ex.get('agents_check') or {}
    ok = {k: v.get('works') for k, v in check.items()}
    if 'single' in check and 'events' in check and None not in ok.values():
        c = check['single']
        text += (f' With the real agents (`scripts/launch_swarm.py --composed`, '
                 f'{c["agents"]} agents, {c["duration_s"]:g} simulated seconds on `/clock`) '
                 'the monitor heard ' + ' and '.join(
                     f'{check[k]["agents_heard"]}/{check[k]["agents"]} agents moving '
                     f'{fmt_num(check[k]["total_displacement"], 0)} m in total under the '
                     f'{name}' for k, name in (('single', 'SingleThreadedExecutor'),
                                               ('events', 'EventsExecutor'))) + '.')
    if chosen == 'SingleThreadedExecutor' and events_cheaper:
        if ok.get('events') is False:
            text += (' So the SingleThreadedExecutor stays: the EventsExecutor is cheaper, '
                     'but the agents do not run under it on sim time (the `make_executor` '
                     'docstring reports the same for rclpy 7.1). Switching is worth it once '
                     'that is understood and fixed; wall-clock runs can opt in with '
                     '`SWARM_EXECUTOR=events`.')
        elif ok.get('events') and ok.get('single'):
            text += (' The agents run under both, so the numbers argue for making the '
                     'EventsExecutor the default of `make_executor`.')
        else:
            text += (' It stays the default because, per the `make_executor` docstring, the '
                     "EventsExecutor's timers did not fire on `/clock` with `use_sim_time` "
                     'in rclpy 7.1 (not re-checked in this run: --executor-check-agents).')
    elif chosen == 'EventsExecutor' and not events_cheaper:
        text += ' On these numbers the SingleThreadedExecutor would be the cheaper default.'
    return lines + [text]


def write_markdown(path: pathlib.Path, results: dict) -> None:
    m, c, s = results['machine'], results['config'], results['sections']
    dirty = ' (with uncommitted changes in the working tree)' if m['git_dirty'] else ''
    lines = ['# Benchmarks', '',
             'Generated by `scripts/env.sh python benchmarks/run_all.py` '
             f'({shlex.join(c["argv"]) or "default arguments"}); do not edit by hand. '
             'Raw figures: `benchmarks.json` next to this file.', '',
             f'Machine: {m["cpu_count"]} cores, Python {m["python"]}, {m["platform"]}; '
             f'load average {m["loadavg_start"][0]:.2f} at the start and '
             f'{m["loadavg_end"][0]:.2f} at the end; {m["date"]}; commit '
             f'`{m["git_commit"][:12]}`{dirty}.'
             + (f' {c["note"]}' if c['note'] else ''), '']
    # Each section's figures come from the last run that measured it (the JSON keeps
    # every --update run; the report names only the ones its figures come from).
    source = {name: u for u in results.get('updates', []) for name in u['sections']}
    if source:
        lines += ['Sections measured by a separate `--update` run (the others by the run '
                  'above):', '']
    for u in results.get('updates', []):
        names = [name for name in u['sections'] if source[name] is u]
        if not names:
            continue
        u_dirty = ' with uncommitted changes' if u['git_dirty'] else ''
        argv = [a for i, a in enumerate(u['argv'])
                if a != '--note' and (i == 0 or u['argv'][i - 1] != '--note')]
        lines += [f'{", ".join(names)}: measured on {u["date"]} at commit '
                  f'`{u["git_commit"][:12]}`{u_dirty} (load average '
                  f'{u["loadavg_start"][0]:.2f} at the start and {u["loadavg_end"][0]:.2f} '
                  f'at the end) by `run_all.py {shlex.join(argv)}`.'
                  + (f' {u["note"]}' if u['note'] else ''), '']
    lines += [f'Times are medians of {c["repeats"]} runs (DSDV: {c["dsdv_repeats"]} random '
              'graph(s) per size); sizes scale the thesis scenario (50 agents in '
              '100 m x 100 m, 314 m^2 formation, 20:20:10 types) at constant density.', '',
              '## Scaling per algorithm', '']
    lines += scaling_table(results)
    if s.get('world'):
        lines += ['', '## pybullet world (scripts/sim_benchmark.py)', '',
                  '| Robots | Physics rate | Real-time factor | CPU real-time factor | '
                  'Wall per step | Physics share | Max tilt | Min ground clearance |',
                  '|---|---|---|---|---|---|---|---|']
        for r in s['world']:
            lines.append(f'| {r["robots"]} | {r["physics_hz"]:g} Hz | '
                         f'{fmt_num(r["real_time_factor"], 1)} | '
                         f'{fmt_num(r["cpu_real_time_factor"], 1)} | '
                         f'{fmt_s(r["ms_per_step"] / 1e3)} | '
                         f'{100 * r["physics_share"]:.0f} % | {r["max_tilt_deg"]:.1f} deg | '
                         f'{100 * r["min_ground_clearance_m"]:.1f} cm |')
        lines += ['', f'Each run: {s["world"][0]["seconds"]:g} simulated seconds on rough '
                  'terrain in the +/-50 m workspace (DIRECT mode, the three types 20:20:10), '
                  'every robot driven towards a new random velocity up to 0.5 m/s every 2 s '
                  'by a 50 Hz controller, the state (poses and velocities) read after every '
                  "physics step, the worst case. Physics share: the time inside Bullet's "
                  'step; the rest is the Python side (forces, state reads).']
    if 'evaluator' in s:
        ev = s['evaluator']
        lines += ['', '## Headless evaluator', '',
                  f'Whole trials of scripts/evaluate.py (`run_trial`): {ev["agents"]} agents, '
                  f'{ev["beacons"]} beacons, {ev["shape"]}, {ev["method"]}, bounded to '
                  f'{ev["duration_bound_s"]:g} simulated seconds (--eval-duration; '
                  f'{ev["settled_share"] * 100:.0f} % of the trials settled within it).', '',
                  '| Wall per trial | CPU per trial | Sim-s per trial | Sim-s per wall-s | '
                  'Trials/min (one process) | Trials/min (all cores, from CPU time) |',
                  '|---|---|---|---|---|---|',
                  f'| {ev["wall_per_trial_s"]:.1f} s | {ev["cpu_per_trial_s"]:.1f} s | '
                  f'{ev["sim_s_per_trial"]:.0f} | {ev["sim_s_per_wall_s"]:.2f} | '
                  f'{ev["trials_per_min_one_process"]:.2f} | '
                  f'{ev["trials_per_min_all_cores"]:.2f} ({ev["cores"]} cores) |']
    if 'throughput' in s:
        lines += throughput_lines(s['throughput'])
    if 'executor' in s:
        ex = s['executor']
        lines += ['', '## Executor', '',
                  f'benchmarks/bench_executor.py: {ex["nodes"]} nodes in one process, a '
                  f'{ex["rate_hz"]:g} Hz wall-clock timer publishing and one subscription '
                  f'each, {ex["seconds"]:g} s per executor.', '']
        lines += executor_paragraph(ex)
    lines += ['', '## ROS 2 swarm (scripts/launch_swarm.py)', '']
    if s.get('ros'):
        lines += ['| Agents | Mode | Real-time factor once started | Start-up (wall) | '
                  'Real-time factor, whole run | CPU cores | Peak memory (PSS) | Outcome |',
                  '|---|---|---|---|---|---|---|---|']
        for r in s['ros']:
            startup = r.get('startup_wall_seconds')
            lines.append(f'| {r["agents"]} | {r["mode"]} | '
                         f'{fmt_num(r.get("steady_real_time_factor"))} | '
                         f'{fmt_s(startup) if startup is not None else "n/a"} | '
                         f'{fmt_num(r.get("real_time_factor"))}'
                         f' | {fmt_num(r.get("cpu_cores_used"))} | '
                         f'{fmt_num(r.get("peak_pss_mb") or r.get("peak_rss_mb"), 0)} MB | '
                         f'{r.get("outcome") or r.get("error", "")} |')
        lines.append('')
        lines.append(f'Each run: {c["ros_duration"]:g} simulated seconds of the thesis '
                     'scenario (15 % beacons, circle_314, bubble). Start-up: wall seconds '
                     'until the launcher had heard every agent (processes, DDS discovery, '
                     'first commands; the world waits for them). Real-time factor once '
                     'started: simulated over wall seconds from then to the end. Peak '
                     'memory: proportional set size of every process of the run (pages '
                     'shared by k processes counted 1/k in each), sampled every 10 s.')
    else:
        lines += ['Not run (slow). Run it with '
                  '`scripts/env.sh python benchmarks/run_all.py --ros --ros-sizes 20,50,100 '
                  '--ros-duration 30` (per-process and composed at each size, a few minutes '
                  'each on 2 cores).']
    lines += ['', '## Targets (issues 6, 9 and 23)', '',
              '| Target | Measured | Wanted | Result | Note |', '|---|---|---|---|---|']
    for t in results['targets']:
        if t['unit'] == 's':
            value = fmt_s(t['value'])
        else:
            value = fmt_num(t['value'])
        wanted = f'{t["op"]} {t["bound"]:g} {t["unit"]}'
        verdict = {True: 'met', False: 'missed', None: 'not measured'}[t['met']]
        lines.append(f'| {t["target"]} | {value} | {wanted} | {verdict} | {t["note"]} |')
    path.write_text('\n'.join(lines) + '\n', encoding='utf-8')


def throughput_lines(tp: dict) -> list[str]:
    """The throughput section (issue 23): its command and the large swarm."""
    c, big = tp['issue_command'], tp['large_swarm']
    bound = ('' if c['duration_bound_s'] is None
             else f', each bounded to {c["duration_bound_s"]:g} simulated seconds')
    return ['', '## Throughput (issue 23)', '',
            f'`{c["command"]}`{bound}, run as a child process and timed from start to '
            f'exit: {c["trials"]} trials in {c["wall_s"]:.1f} s, **{c["trials_per_min"]:.1f} '
            f'trials a minute** ({c["settled"]} settled; the trials\' own walls add up to '
            f'{c["trial_wall_sum_s"]:.1f} s on {c["workers"]} workers). '
            f'{big["agents"]} agents headless (`run_trial`, the thesis circle scaled by '
            f'{big["shape_scale"]:g}, the first {big["duration_bound_s"]:g} simulated '
            f'seconds): {big["wall_s"]:.1f} s wall, {big["cpu_s"]:.1f} s CPU, '
            f'**{big["real_time_factor"]:.2f}x real time**.']
