"""
``sim_conformance``: check any simulator against ROS 2's simulation standard, clause by clause.

Also ``python -m r2d2_sim.conformance``. Prints a matrix (each clause PASS,
FAIL with a one-line reason, or SKIP with what it needs), a summary line,
and optionally JUnit XML and a Markdown table. Exit status: 0 when a clause
ran and none failed, 1 when one failed or nothing was checked (no simulator's
features read, every clause skipped), 2 for a usage error (one line on stderr:
a bad option, or a world or asset given that the simulator refused), a
kit that cannot start or cannot tell which simulator to check (none at the
prefix but some elsewhere, or several there: it touches none), 130 after
Ctrl-C. Every line it prints is short, whatever the simulator sends.
"""

import argparse
import os
import signal
import sys
import threading
from types import FrameType
from typing import Any, List, Optional, Tuple

from r2d2_sim.apps.cli import domain_id_arg, EXIT_INTERRUPTED, finite_number, positive_number
from r2d2_sim.conformance.clause import Clause, feature_text, one_line, Outcome
from r2d2_sim.conformance.clauses import CLAUSES
from r2d2_sim.conformance.discovery import ACTION
from r2d2_sim.conformance.report import (
    exit_status, markdown_matrix, matrix, summary, write_junit)
from r2d2_sim.conformance.runner import Kit, select
from r2d2_sim.conformance.target import (
    KitError, KitOptions, namespace_problem, topic_problem)

__all__ = ['main', 'build_parser']

PROG = 'sim_conformance'
EXAMPLES = """\
examples:
  sim_conformance                                   # at the root: O3DE, Isaac Sim 6, r2d2_sim
  sim_conformance --prefix /gzserver --asset /models/box.sdf   # Gazebo (ros_gz)
  sim_conformance --asset cube.urdf --junit conformance.xml    # r2d2_sim, for CI
  sim_conformance --only STATE,STEP --skip STEP-07             # some groups, one clause less

Every clause starts from STOPPED (SetSimulationState), so the kit resets the
simulator many times: run it where nothing else uses that simulator.
"""


def point_arg(text: str) -> Tuple[float, float, float]:
    """Parse ``X,Y,Z`` (three finite numbers; an argparse type)."""
    parts = text.split(',')
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f'must be X,Y,Z, got {text!r}')
    x, y, z = (finite_number(p) for p in parts)
    return x, y, z


def build_parser() -> argparse.ArgumentParser:
    """Return the command line of ``sim_conformance``."""
    parser = argparse.ArgumentParser(
        prog=PROG, formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EXAMPLES,
        description='Check a simulator against simulation_interfaces (ROS 2 Jazzy 1.5), clause '
                    'by clause. Finds the services and the action by type under --prefix.')
    parser.add_argument('--prefix', default='/', help='namespace of the simulator\'s services: '
                        '/ (default), /gzserver, /isaacsim...')
    parser.add_argument('--domain', type=domain_id_arg, default=None, metavar='ID',
                        help='ROS domain id (default: ROS_DOMAIN_ID, else 0)')
    parser.add_argument('--asset', default='', metavar='URI',
                        help='something SpawnEntity takes by uri (cube.urdf, a .sdf or .usd file)')
    parser.add_argument('--world', default='', metavar='URI',
                        help='a world LoadWorld takes (default: one GetAvailableWorlds lists)')
    parser.add_argument('--timeout', type=positive_number, default=10.0, metavar='S',
                        help='longest wait for discovery or any one reply, in seconds (10)')
    parser.add_argument('--total-timeout', type=positive_number, default=None, metavar='S',
                        help='longest the whole run may take, in seconds (default: 30 '
                        'timeouts); the clauses past it are not run')
    parser.add_argument('--only', action='append', default=[], metavar='IDS',
                        help='clauses or groups to run, comma-separated (STATE,SPAWN-0*)')
    parser.add_argument('--skip', action='append', default=[], metavar='IDS',
                        help='clauses or groups to leave out, comma-separated')
    parser.add_argument('--junit', metavar='FILE', help='also write JUnit XML here')
    parser.add_argument('--markdown', metavar='FILE', help='also write the matrix as Markdown')
    parser.add_argument('--free-space', type=point_arg, default=(20.0, 20.0, 5.0),
                        metavar='X,Y,Z', help='a point with 20 m of free room along +x, where the '
                        'kit puts what it spawns (default 20,20,5)')
    parser.add_argument('--world-frame', default='world', metavar='NAME',
                        help='the world frame\'s name, besides "" and world')
    parser.add_argument('--clock-topic', default='/clock', metavar='TOPIC',
                        help='where simulated time is published (default /clock)')
    parser.add_argument('--list', action='store_true',
                        help='list the clauses (id, needs, title) and exit')
    return parser


def _names(values: List[str]) -> List[str]:
    return [n for value in values for n in value.split(',') if n.strip()]


def _header(kit: Kit) -> str:
    t = kit.target
    served = sorted(k for k in t.interfaces if k != ACTION)
    action = ' and the action' if ACTION in t.interfaces else ', no action'
    lines = [f'{PROG}: prefix {t.prefix!r}, ROS domain {t.domain_id}']
    if t.features is None:
        lines.append(f'  {t.features_error}')
    else:
        lines.append(f'  {len(served)} of 22 services{action}; {len(t.features)} of 32 features '
                     f'declared; spawn formats: {", ".join(t.spawn_formats) or "none"}; '
                     f'{t.clock.topic}: {"yes" if t.clock.present else "none"}')
        undeclared = sorted(set(f.split('|')[0] for c in CLAUSES for f in c.features)
                            - set(t.features))
        if undeclared:
            lines.append(f'  not declared: {feature_text(undeclared)}')
    world = t.world.described()
    if world:
        lines.append(f'  {world}')
    if t.others:
        lines.append(f'  note: not checked, other simulators on this domain: '
                     f'{", ".join(t.others)} (--prefix NS checks one)')
    return '\n'.join(one_line(line) for line in lines)


INTERRUPTED = (f'{PROG}: interrupted: leaving the simulator as found (Ctrl-C again to leave it '
               'as it is)')


def output_problem(flag: str, path: Optional[str]) -> str:
    """Return why the kit could not write ``path`` (``--junit``), in one line; '' if it can."""
    if not path:
        return ''
    folder = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(path):
        return f'{flag} {path}: is a directory'
    if not os.path.isdir(folder):
        return f'{flag} {path}: no such directory {folder}'
    if not os.access(path if os.path.exists(path) else folder, os.W_OK):
        return f'{flag} {path}: not writable'
    return ''


class CtrlC:
    """
    Ctrl-C (SIGINT), taken where the kit checks for it, never where it lands.

    Python's own handler raises KeyboardInterrupt in whatever the main
    thread runs, rclpy's message handling included: measured, it landed in
    a generated message's ``__init__`` called from rclpy's C code (a
    traceback, exit status 1, the run going on) and in code that lost it
    (the run going on, exit status 0). Here the handler only counts, and
    :meth:`check` takes one Ctrl-C at a time: the kit calls it before each
    clause and between the spins of every wait (at most 50 ms apart), the
    command line between its steps. In ``mode`` ``'run'`` the first Ctrl-C
    raises KeyboardInterrupt (the run ends, the simulator is put back); in
    ``'restore'`` the first only says so, and a second raises (the restore
    is skipped); in ``'done'`` (the simulator put back) none raises.
    A context manager: installs its handler in the main thread, and puts
    the one it found back.
    """

    def __init__(self) -> None:
        self.received = 0  # SIGINTs counted by the handler
        self.taken = 0  # of those, the ones a check took
        self.mode = 'run'
        self._previous: Any = None

    def __enter__(self) -> 'CtrlC':
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._count)
        return self

    def __exit__(self, *exc_info: object) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)

    def _count(self, signum: int, frame: Optional[FrameType]) -> None:
        self.received += 1

    def check(self) -> None:
        """Take the Ctrl-Cs not taken yet: say so at the first; raise as ``mode`` says."""
        while self.taken < self.received:
            self.taken += 1
            if self.taken == 1:
                print(INTERRUPTED, file=sys.stderr, flush=True)
                if self.mode == 'run':
                    raise KeyboardInterrupt
            elif self.mode != 'done':
                raise KeyboardInterrupt


def main(argv: Optional[List[str]] = None) -> int:
    """Run the kit from the command line; return the exit status."""
    args = build_parser().parse_args(sys.argv[1:] if argv is None else argv)
    try:
        clauses = select(_names(args.only), _names(args.skip))
        if args.list:
            for c in clauses:
                print(f'{c.id:<14} {c.title}  [{feature_text(c.features) or "-"}]')
            return 0
        for flag, value, problem in (
                ('--prefix', args.prefix, namespace_problem(args.prefix)),
                ('--clock-topic', args.clock_topic, topic_problem(args.clock_topic))):
            if problem:
                raise KitError(one_line(f'{flag} {value!r}: {problem}'))
        for flag, path in (('--junit', args.junit), ('--markdown', args.markdown)):
            problem = output_problem(flag, path)  # before the run, not after it
            if problem:
                raise KitError(one_line(problem))
    except KitError as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 2
    with CtrlC() as ctrl_c:
        status = _run(kit_options(args), clauses, args, ctrl_c)
        ctrl_c.mode = 'done'
        ctrl_c.check()  # a Ctrl-C at the very end: the simulator was put back
        return EXIT_INTERRUPTED if ctrl_c.taken else status


def kit_options(args: argparse.Namespace) -> KitOptions:
    """Return the KitOptions of a parsed command line."""
    return KitOptions(prefix=args.prefix, domain_id=args.domain, asset=args.asset,
                      world=args.world, timeout_s=args.timeout, free_space=args.free_space,
                      world_frame=args.world_frame, clock_topic=args.clock_topic,
                      total_timeout_s=args.total_timeout)


def _run(options: KitOptions, clauses: List[Clause], args: argparse.Namespace,
         ctrl_c: CtrlC) -> int:
    """Connect, run the clauses, put the simulator back, report; return the exit status."""
    try:
        kit = Kit(options, check=ctrl_c.check)
    except KitError as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 2
    outcomes: List[Outcome] = []

    def each(outcome: Outcome) -> None:
        print(matrix([outcome]), flush=True)
        ctrl_c.check()
    try:
        kit.connect()
        print(_header(kit), flush=True)
        outcomes = kit.run(clauses, each=each)
    except KitError as exc:  # which simulator to check is not clear: none is touched
        kit.close()
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # the first Ctrl-C (CtrlC said so): put the simulator back
        pass
    ctrl_c.mode = 'restore'  # from here the first Ctrl-C only says so; a second skips it
    try:
        problems = kit.close()
        ctrl_c.check()
    except KeyboardInterrupt:
        print(f'{PROG}: interrupted again: the simulator was left as it is', file=sys.stderr)
        return EXIT_INTERRUPTED
    ctrl_c.mode = 'done'
    for problem in problems:
        print(f'{PROG}: could not leave the simulator as found: {problem}', file=sys.stderr)
    if ctrl_c.taken:
        return EXIT_INTERRUPTED
    return _report(kit, outcomes, args)


def _report(kit: Kit, outcomes: List[Outcome], args: argparse.Namespace) -> int:
    """Print the summary, write the outputs asked for; return the exit status."""
    print(summary(outcomes, f'prefix {kit.target.prefix!r}'))
    properties = {'prefix': kit.target.prefix, 'domain_id': str(kit.target.domain_id),
                  'features': ' '.join(sorted(kit.target.features or ()))}

    def write_markdown(path: str) -> None:
        with open(path, 'w', encoding='utf-8') as handle:
            handle.write(markdown_matrix(outcomes))
    writes = ((args.junit, lambda path: write_junit(outcomes, path, properties)),
              (args.markdown, write_markdown))
    for path, write in writes:
        if not path:
            continue
        try:
            write(path)
        except OSError as exc:  # named here: a failed write (a full disk) has no filename
            print(f'{PROG}: error: cannot write {path}: {exc.strerror or exc}', file=sys.stderr)
            return 2
    status = exit_status(outcomes)
    for problem in kit.setup_problems():  # the user's world or asset, refused: one line each
        print(f'{PROG}: error: {problem}', file=sys.stderr)
    unchecked = kit.unchecked()
    if status == 0 and unchecked:
        # No simulator read, or every clause skipped: the run says nothing of the simulator.
        print(f'{PROG}: error: {unchecked}', file=sys.stderr)
    if status == 0 and kit.setup_problems():
        return 2  # what the user gave was refused: theirs to fix first
    return 1 if status == 0 and unchecked else status
