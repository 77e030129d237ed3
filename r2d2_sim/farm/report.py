"""
A farm's report from its outcomes: report.md, report.json and trajectories.png.

Each run of a farm is a record (one JSON line a worker wrote: the test's
node id and the rootdir it is relative to, the run's number in that test,
whether it was a Hypothesis property's final example, and the
:class:`~r2d2_sim.farm.run.Outcome`; a run without one, whose process died
or which raised, has ``crashed`` instead: what happened, its seed and, from
the pytest plugin, its ``scenario``; a pytest run's record has its ``test``'s
result too, and a case passes only when its verdict passed and its test did
not fail on its own).
:func:`write_report` numbers them in node id order (so a case keeps its
number however the workers were ordered) and writes:

- ``report.json``: every case with its verdict, measures, scenario, recording
  and rerun command, and the summary;
- ``report.md``: success rate, goals reached, the distributions of time to
  goal and clearance (min, median, p90, max), the slowest and the closest
  cases, and each failure with its seed, reason, recording and rerun command;
- ``trajectories.png``: every trajectory over the world's map (its walls and
  boxes, each case's obstacles faint, a failure's in red), failures in red,
  starts and goals marked.
"""

import datetime
import json
import math
from pathlib import Path
import re
import shlex
from typing import Any, Dict, List, Optional, Sequence, Tuple, TYPE_CHECKING, Union

import numpy

from r2d2_sim.farm.scenario import Box, Scenario

if TYPE_CHECKING:  # typing only: matplotlib is imported when a picture is drawn
    from matplotlib.axes import Axes

__all__ = ['write_report', 'percentile', 'case_key', 'REPORT_JSON', 'REPORT_MD',
           'TRAJECTORIES_PNG']

REPORT_JSON = 'report.json'
REPORT_MD = 'report.md'
TRAJECTORIES_PNG = 'trajectories.png'
# Cases listed as the slowest and the closest.
LISTED = 5


def percentile(values: Sequence[float], q: float) -> float:
    """
    Return the value below which q % (0..100) of ``values`` fall; NaN for no values.

    numpy's default (linear) definition: between the two nearest of the sorted
    values, at (n - 1) * q / 100.
    """
    if len(values) == 0:
        return math.nan
    return float(numpy.percentile(values, q))


def case_key(record: Dict[str, Any]) -> Tuple[List[Union[int, str]], int]:
    """Sort key of a record: its node id with numbers compared as numbers, then its run."""
    parts = re.split(r'(\d+)', record['nodeid'])
    return [int(p) if p.isdigit() else p for p in parts], record.get('run', 0)


def _distribution(values: Sequence[float]) -> Dict[str, Any]:
    if not values:
        return {'runs': 0}
    return {'runs': len(values), 'min': min(values), 'median': percentile(values, 50.0),
            'p90': percentile(values, 90.0), 'max': max(values)}


# The farm's rerun of a pytest case; a case may carry a command of its own (OpenSCENARIO).
RERUN = 'python -m r2d2_sim.farm rerun'


def rerun_command(report: Path, case: int) -> str:
    """Return the command that reruns case ``case`` of the report at ``report``, recording it."""
    return f'{RERUN} {shlex.quote(str(report))} --case {case}'


def write_report(records: List[Dict[str, Any]], directory: Path, *,
                 invocation_dir: Optional[str] = None, rootdir: Optional[str] = None,
                 picture: bool = True) -> Dict[str, Path]:
    """
    Write report.json, report.md and (with ``picture``) trajectories.png into ``directory``.

    ``records`` are the farm's JSON lines, in any order; ``invocation_dir``
    and ``rootdir`` are where pytest's main process ran and its root (a
    record's own rootdir comes first: its node id is relative to that).
    Returns the paths written, by file name.
    """
    directory.mkdir(parents=True, exist_ok=True)
    report_json = directory / REPORT_JSON
    cases = []
    for number, record in enumerate(sorted(records, key=case_key)):
        outcome = record['outcome']
        crashed = record.get('crashed')
        farm = record.get('farm') or {}
        # A run passes when its verdict did and its test did not fail on its own (an
        # assertion of the test's while every verdict of it passed).
        test = record.get('test') or {}
        reason = crashed['reason'] if crashed else outcome['reason']
        if not reason and test.get('own'):
            reason = f'the verdict passed, the test failed: {test.get("message") or "?"}'
        cases.append({'case': number, 'nodeid': record['nodeid'],
                      'rootdir': record.get('rootdir') or rootdir, 'run': record.get('run', 0),
                      'property': record.get('property', False),
                      'worker': record.get('worker', ''),
                      'passed': (outcome is not None and outcome['passed']
                                 and not test.get('own')),
                      'crashed': crashed is not None, 'reason': reason, 'test': record.get('test'),
                      'seed': (farm.get('seed', crashed.get('seed')) if crashed
                               else outcome['scenario']['seed']),
                      'recording': None if crashed else outcome['recording'],
                      'rerun': record.get('rerun') or rerun_command(report_json, number),
                      'outcome': outcome,
                      'first_failure': record.get('first_failure'),
                      'farm': record.get('farm'), 'traceback': (crashed or {}).get('traceback'),
                      'scenario': record.get('scenario')})
    summary = _summary(cases)
    data = {'date': datetime.datetime.now().astimezone().isoformat(timespec='seconds'),
            'invocation_dir': invocation_dir, 'rootdir': rootdir, 'summary': summary,
            'cases': cases}
    report_json.write_text(json.dumps(data, indent=1, sort_keys=True) + '\n', encoding='utf-8')
    written = {REPORT_JSON: report_json}
    report_md = directory / REPORT_MD
    report_md.write_text(_markdown(data), encoding='utf-8')
    written[REPORT_MD] = report_md
    if picture:
        png = directory / TRAJECTORIES_PNG
        draw_trajectories(cases, png)
        written[TRAJECTORIES_PNG] = png
    return written


def _summary(cases: List[Dict[str, Any]]) -> Dict[str, Any]:
    # A crashed case has no outcome: it counts among the runs, not in the measures.
    outcomes = [c['outcome'] for c in cases if c['outcome'] is not None]
    reached = [o['time_to_goal_s'] for o in outcomes if o['time_to_goal_s'] is not None]
    simulated = [o['steps'] for o in outcomes]
    return {'runs': len(cases), 'passed': sum(c['passed'] for c in cases),
            'failed': sum(not c['passed'] and not c['crashed'] for c in cases),
            'crashed': sum(c['crashed'] for c in cases), 'goal_reached': len(reached),
            'touched': sum(bool(o['contacts']) for o in outcomes),
            'tipped': sum(o['tipped_s'] is not None for o in outcomes),
            'time_to_goal_s': _distribution(reached),
            'clearance_m': _distribution([o['clearance_m'] for o in outcomes]),
            'wall_s': _distribution([o['wall_s'] for o in outcomes]),
            'physics_steps': sum(simulated), 'wall_s_total': sum(o['wall_s'] for o in outcomes)}


def _rate(count: int, total: int) -> str:
    return f'{count} of {total} ({100.0 * count / total:.1f} %)' if total else '0 of 0'


def _row(name: str, unit: str, distribution: Dict[str, Any]) -> str:
    if not distribution['runs']:
        return f'| {name} | - | - | - | - | 0 |'
    values = ' | '.join(f'{distribution[k]:.3f}' for k in ('min', 'median', 'p90', 'max'))
    return f'| {name} ({unit}) | {values} | {distribution["runs"]} |'


def _test_name(case: Dict[str, Any]) -> str:
    return case['nodeid'].rsplit('/', 1)[-1]


def _markdown(data: Dict[str, Any]) -> str:
    summary, cases = data['summary'], data['cases']
    total = summary['runs']
    how = (f'Every case below reruns, recording its MCAP, with the command given (`{RERUN}`)'
           if all(c['rerun'].startswith(RERUN) for c in cases)
           else 'Every case below says the command that runs it again')
    lines = ['# Farm report', '',
             f'{data["date"]}: {total} runs. {how}; `report.json` has every '
             'case with its scenario and measures.', '',
             '| | |', '|---|---|',
             f'| passed | {_rate(summary["passed"], total)} |',
             f'| goal reached | {_rate(summary["goal_reached"], total)} |',
             f'| touched something | {summary["touched"]} |',
             f'| tipped over | {summary["tipped"]} |',
             *([f'| crashed (no verdict: its process died or it raised) | '
                f'{summary["crashed"]} |'] if summary.get('crashed') else []),
             f'| simulated | {summary["physics_steps"]:,} physics steps in '
             f'{summary["wall_s_total"]:.1f} s of run wall time |', '',
             '## Distributions', '',
             '| measure | min | median | p90 | max | runs |', '|---|---|---|---|---|---|',
             _row('time to goal', 's', summary['time_to_goal_s']),
             _row('clearance', 'm', summary['clearance_m']),
             _row('wall time of a run', 's', summary['wall_s']), '']
    judged = [c for c in cases if c['outcome'] is not None]
    reached = [c for c in judged if c['outcome']['time_to_goal_s'] is not None]
    slowest = sorted(reached, key=lambda c: (-c['outcome']['time_to_goal_s'], c['case']))
    lines += [f'## The slowest to the goal ({min(LISTED, len(slowest))})', '',
              '| case | test | seed | time to goal (s) | clearance (m) |', '|---|---|---|---|---|']
    lines += [f'| {c["case"]} | `{_test_name(c)}` | {c["seed"]} | '
              f'{c["outcome"]["time_to_goal_s"]:.3f} | {c["outcome"]["clearance_m"]:.3f} |'
              for c in slowest[:LISTED]]
    closest = sorted(judged, key=lambda c: (c['outcome']['clearance_m'], c['case']))
    lines += ['', f'## The closest ({min(LISTED, len(closest))})', '',
              '| case | test | seed | clearance (m) | to | at (s) |', '|---|---|---|---|---|---|']
    for c in closest[:LISTED]:
        o = c['outcome']
        at = '-' if o['closest_s'] is None else f'{o["closest_s"]:.3f}'
        lines.append(f'| {c["case"]} | `{_test_name(c)}` | {c["seed"]} | '
                     f'{o["clearance_m"]:.3f} | {o["closest"] or "-"} | {at} |')
    failures = [c for c in judged if not c['passed']]
    lines += ['', f'## Failures ({len(failures)})', '']
    if not failures:
        lines.append('None.')
    for c in failures:
        lines += [f'### Case {c["case"]}: `{_test_name(c)}`, seed {c["seed"]}', '',
                  f'- reason: {c["reason"]}',
                  f'- recording: `{c["recording"] or "none"}`',
                  f'- rerun: `{c["rerun"]}`',
                  f'- scenario: `{Scenario.from_dict(c["outcome"]["scenario"]).to_json()}`']
        if c['first_failure'] is not None:
            first = Scenario.from_dict(c['first_failure'])
            count = len(first.obstacles)
            lines.append(f'- shrunk by Hypothesis from a first failing scenario of {count} '
                         f'box{"" if count == 1 else "es"}: `{first.to_json()}`')
        lines.append('')
    crashes = [c for c in cases if c['crashed']]
    if crashes:
        lines += [f'## Crashed ({len(crashes)})', '',
                  'No verdict: the process running it died, or the run raised. Not run again; '
                  'its seed reruns it.', '']
    for c in crashes:
        lines += [f'### Case {c["case"]}: `{_test_name(c)}`, seed {c["seed"]}', '',
                  f'- {c["reason"]}', f'- on: `{c["worker"] or "the main process"}`',
                  f'- run it again: `{c["rerun"]}`',
                  '']
    return '\n'.join(lines).rstrip('\n') + '\n'


# -- the picture -----------------------------------------------------------------------

def _outline(axes: 'Axes', box: Box, **style: Any) -> None:
    from matplotlib.patches import Polygon
    axes.add_patch(Polygon(box.corners(), closed=True, **style))


def draw_trajectories(cases: List[Dict[str, Any]], path: Path) -> None:
    """Draw every case's trajectory over its world's map into ``path`` (a PNG, Agg)."""
    # A Figure of its own (no pyplot) draws with Agg and leaves pyplot's backend alone.
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle, Rectangle
    from r2d2_sim.farm.maps import world_boxes

    figure = Figure(figsize=(9, 7.5), dpi=110)
    axes = figure.add_subplot()
    cases = [c for c in cases if c['outcome'] is not None]  # a crash ran no trajectory
    scenarios = [Scenario.from_dict(c['outcome']['scenario']) for c in cases]
    for world in sorted({s.world for s in scenarios if s.world}):
        for box in world_boxes(world):
            _outline(axes, box, facecolor='0.55', edgecolor='0.3', zorder=2)
    for case, scenario in zip(cases, scenarios):
        failed = not case['passed']
        for box in scenario.obstacles:
            _outline(axes, box, facecolor='none', linewidth=1.2 if failed else 0.5,
                     edgecolor='red' if failed else '0.45', alpha=0.9 if failed else 0.25,
                     zorder=3 if failed else 1)
        goal = scenario.goal
        if goal.kind == 'circle':
            centre = (goal.values[0], goal.values[1])
            axes.add_patch(Circle(centre, goal.values[2], facecolor='none',
                                  edgecolor='green', alpha=0.35, linewidth=0.6))
        else:
            x_min, y_min, x_max, y_max = goal.values
            axes.add_patch(Rectangle((x_min, y_min), x_max - x_min, y_max - y_min,
                                     facecolor='none', edgecolor='green', alpha=0.35))
    for case in sorted(cases, key=lambda c: not c['passed']):  # failures drawn last, on top
        trajectory = case['outcome']['trajectory']
        failed = not case['passed']
        xs, ys = [p[1] for p in trajectory], [p[2] for p in trajectory]
        axes.plot(xs, ys, color='red' if failed else 'tab:blue', linewidth=1.4 if failed else 0.6,
                  alpha=0.95 if failed else 0.45, zorder=5 if failed else 4)
    starts = [s.start for s in scenarios]
    axes.scatter([p.x for p in starts], [p.y for p in starts], marker='o', s=9, color='black',
                 zorder=6, label='start')
    goals = [s.goal_point for s in scenarios]
    axes.scatter([g[0] for g in goals], [g[1] for g in goals], marker='x', s=14, color='green',
                 zorder=6, label='goal')
    failures = sum(not c['passed'] for c in cases)
    axes.set_title(f'{len(cases)} runs, {failures} failed (red)')
    axes.set_xlabel('x (m)')
    axes.set_ylabel('y (m)')
    axes.set_aspect('equal')
    axes.autoscale_view()
    axes.legend(loc='upper right', fontsize='small')
    axes.grid(True, linewidth=0.3)
    figure.tight_layout()
    figure.savefig(str(path))
    # Hundreds of translucent lines make a true-colour PNG of about 450 kB; a
    # palette of 128 colours looks the same at a quarter of that (for a CI artifact).
    from PIL import Image
    with Image.open(path) as image:
        image.convert('RGB').quantize(128).save(path, optimize=True)
