"""
Variations: a multi-document parameter file, each scenario per document, on the farm's executors.

scenario_execution reads a ``--scenario-parameter-file`` with several YAML
documents as several runs of each scenario of the file (``name-0``,
``name-1``...; with one document, or none, plain ``name``) and runs them one
after another. Here each scenario of each document is a :class:`Task` of its
own (the scenario file, the scenario, the document and its index, the test
case's name), run by :func:`run_document` in whichever process takes it, so
the documents of a file fan out over cores;
each run is in lockstep and seeded by its document's ``seed``, so its
verdict does not depend on where or when it ran. :func:`run_variations`
hands the tasks to the farm's executors (:mod:`r2d2_sim.farm.executors`:
local processes by default, a Ray or a Dask cluster when asked), as one
:class:`DocumentsJob`, a crash reported as that task's failure and never
retried, and writes one JUnit file (``test.xml``, a test case per task, as
scenario_execution names them) and the farm's
report (``farm/report.md``, ``report.json``, ``trajectories.png``).

A worker parses the scenario file once and copies the model for each
document it runs (scenario_execution's own multi-document path does the
same: parsing is about 0.4 s, a copy 0.06 s).
"""

import contextlib
import copy
from dataclasses import dataclass
import functools
import importlib
import io
import os
from pathlib import Path
import shlex
import tempfile
import time
from typing import Any, Callable, Dict, Iterable, List, NamedTuple, Optional, Sequence, Tuple
from xml.sax.saxutils import quoteattr

import py_trees
import yaml

from r2d2_sim.errors import ScenarioError

Status = py_trees.common.Status

__all__ = ['Task', 'Verdict', 'DocumentsJob', 'read_documents', 'tasks_of', 'run_document',
           'check_parses', 'run_variations', 'executor_map', 'write_junit', 'scenario_parameters',
           'simulator_parameters', 'IN_PROCESS']

# The simulation a variation runs against: R2D2 in the worker's own process.
IN_PROCESS = 'r2d2_sim.osc:R2D2Simulation'

Mapper = Callable[[Callable[['Task'], 'Verdict'], Sequence['Task']], Iterable['Verdict']]


class Task(NamedTuple):
    """One scenario of a file with one document of a parameter file: all a worker needs."""

    scenario_file: str              # the .osc file, absolute
    number: int                     # the document's place in the file (0 first)
    document: Optional[Dict[str, Any]]  # {scenario name: {parameter: value}}, None: defaults
    simulation: str = IN_PROCESS    # the simulation class, module:Class
    scenario: str = ''              # the scenario of the file to run ('': its only one)
    name: str = ''                  # the test case's name ('': the scenario's)


class Verdict(NamedTuple):
    """One task's run: scenario_execution's verdict, the reason, the farm's measures."""

    number: int                     # the document's place in the file
    name: str                       # as scenario_execution names it: <scenario>[-<number>]
    passed: bool
    reason: str                     # one line ('' when passed)
    wall_s: float
    outcome: Optional[Dict[str, Any]]  # the farm's Outcome as JSON data (None: no run)

    def same_as(self, other: 'Verdict') -> bool:
        """Return True when two runs of a document agree (verdict and measures, not wall time)."""
        def measures(verdict: 'Verdict') -> Any:
            data = dict(verdict.outcome or {})
            data.pop('wall_s', None)
            return (verdict.number, verdict.name, verdict.passed, verdict.reason, data)
        return measures(self) == measures(other)


def read_documents(path: str) -> List[Optional[Dict[str, Any]]]:
    """
    Return a parameter file's documents, each {scenario: {parameter: value}}.

    ScenarioError (one line) for a file that cannot be read or a document
    that is not such a mapping. A file without a document is one run with
    the scenario's defaults ([None]); a scenario whose value is empty
    (``name:`` alone) keeps its defaults, as scenario_execution reads it.
    """
    try:
        with open(path, encoding='utf-8') as stream:
            documents = [d for d in yaml.safe_load_all(stream) if d is not None]
    except (OSError, yaml.YAMLError) as exc:
        raise ScenarioError(f'parameter file {path}: {exc}'.replace('\n', ' ')) from None
    for index, document in enumerate(documents):
        if not (isinstance(document, dict)
                and all(v is None or isinstance(v, dict) for v in document.values())):
            raise ScenarioError(f'parameter file {path}: document {index} is not '
                                '{scenario name: {parameter: value}}')
    return list(documents) or [None]


def tasks_of(scenario_file: str, parameter_file: Optional[str] = None,
             simulation: str = IN_PROCESS) -> List[Task]:
    """
    Return one task per scenario of the file and document of ``parameter_file``.

    In document order, then the scenarios' order in the file. Each is named
    as scenario_execution names its test case: the scenario's name, with
    ``-N`` for document N when the parameter file has more than one. A
    scenario file that does not parse gives one task per document (named
    ``<file stem>-N``), each of which fails saying so.
    """
    path = os.path.abspath(scenario_file)
    documents: List[Optional[Dict[str, Any]]] = (
        read_documents(parameter_file) if parameter_file else [None])
    several = len(documents) > 1
    scenarios = _scenario_names(path)
    if not scenarios:
        return [Task(path, number, document, simulation, '', f'{Path(path).stem}-{number}')
                for number, document in enumerate(documents)]
    return [Task(path, number, document, simulation, scenario,
                 f'{scenario}-{number}' if several else scenario)
            for number, document in enumerate(documents) for scenario in scenarios]


def _scenario_names(path: str) -> List[str]:
    """Return the names of the scenarios a file declares, in order; [] if it does not parse."""
    from scenario_execution.model.types import ScenarioDeclaration

    from r2d2_sim.osc.entry_points import ensure_registered
    ensure_registered()
    try:
        with contextlib.redirect_stderr(io.StringIO()):  # ANTLR's own line: the run says it
            model = _parsed(path, os.stat(path).st_mtime_ns)[1]
    except Exception:  # scenario_execution's parse errors: ValueError, OSC2Error...
        return []
    return [scenario.name for scenario in model.find_children_of_type(ScenarioDeclaration)]


# -- one document, in a worker ---------------------------------------------------------------


class _QuietLogger:
    """scenario_execution's logger, keeping only errors (a farm of runs would flood the log)."""

    def __init__(self) -> None:
        from scenario_execution.utils.logging import Logger
        self._logger = Logger('scenario_execution', False)
        self.name, self.log_debug = 'scenario_execution', False
        self.errors: List[str] = []

    def info(self, msg: str) -> None:
        pass

    def debug(self, msg: str) -> None:
        pass

    def warning(self, msg: str) -> None:
        pass

    def error(self, msg: str) -> None:
        self.errors.append(msg)


@functools.lru_cache(maxsize=8)
def _parsed(path: str, mtime_ns: int) -> Any:
    """Return (parse tree, model loaded) of a scenario file, once per process and version."""
    from scenario_execution.model.osc2_parser import OpenScenario2Parser
    parser = OpenScenario2Parser(_QuietLogger())
    tree = parser.parse_file(path, False)
    return tree, parser.load_internal_model(tree, path, False, False)


def _parser(logger: Any) -> Any:
    """Return an OpenScenario2Parser whose file parse and model load come from the cache."""
    from scenario_execution.model.osc2_parser import OpenScenario2Parser

    class CachedParser(OpenScenario2Parser):
        def parse_file(self, file: str, log_model: bool = False, error_prefix: str = '') -> Any:
            return _parsed(os.path.abspath(file), os.stat(file).st_mtime_ns)[0]

        def load_internal_model(self, tree: Any, file_name: str, log_model: bool = False,
                                debug: bool = False, skip_imports: bool = False) -> Any:
            path = os.path.abspath(file_name)
            return copy.deepcopy(_parsed(path, os.stat(path).st_mtime_ns)[1])
    return CachedParser(logger)


@functools.lru_cache(maxsize=2)
def _simulation(spec: str) -> Any:
    """Return this process's simulation of class ``spec`` (module:Class), made once."""
    module, _, name = spec.partition(':')
    return getattr(importlib.import_module(module), name)()


def run_document(task: Task) -> Verdict:
    """
    Run one scenario of a file, with one document of a parameter file, here; return its verdict.

    The scenario file is parsed once per process. A document that does not
    fit the scenario (an unknown scenario or parameter) is a failed verdict
    with scenario_execution's one line; so is a task that names no scenario
    of a file that has several, and a run whose simulation found a mistake
    at reset (its ``error``), even when no action of ``osc.r2d2`` ran.
    """
    from r2d2_sim.osc.entry_points import ensure_registered
    ensure_registered()
    from scenario_execution.scenario_execution_base import ScenarioExecution
    started = time.perf_counter()
    logger = _QuietLogger()
    simulation = _simulation(task.simulation)
    execution = ScenarioExecution(debug=False, log_model=False, live_tree=False,
                                  scenario_file=task.scenario_file, output_dir=None,
                                  logger=logger,
                                  register_signal=False, simulation=simulation)
    name = task.name or task.scenario or f'{Path(task.scenario_file).stem}-{task.number}'
    try:
        trees = (_parser(logger).process_file(task.scenario_file) if task.document is None
                 else _with_document(task, logger))
    except Exception as exc:  # scenario_execution's parse errors: ValueError, OSC2Error...
        return Verdict(task.number, name, False, _line(f'parsing failed: {exc}'),
                       time.perf_counter() - started, None)
    chosen = [(tree, params) for tree, params, _ in trees
              if tree.name == task.scenario or not task.scenario]
    if len(chosen) != 1:
        declared = ', '.join(tree.name for tree, _, _ in trees)
        wanted = (f'no scenario {task.scenario!r}' if task.scenario
                  else 'several scenarios, and the task names none')
        return Verdict(task.number, name, False,
                       f'{Path(task.scenario_file).name}: {wanted}; it has: {declared}',
                       time.perf_counter() - started, None)
    (tree, params), = chosen
    # The test case's name (its blackboard namespace too, as in scenario_execution).
    name = tree.name = task.name or tree.name
    execution.scenarios_list = [(tree, params, None)]
    execution.run()
    results = execution.results
    passed = bool(results) and all(r.result for r in results)
    reason = '' if passed else _reason(execution, results, logger)
    error = getattr(simulation, 'error', None)
    if error:  # a mistake found at reset fails the run, whether or not an action met it
        passed, reason = False, _line(error)
    outcome = _outcome(simulation, passed, reason, time.perf_counter() - started)
    return Verdict(task.number, name, passed, reason, time.perf_counter() - started, outcome)


def check_parses(scenario_file: str) -> None:
    """
    Parse the scenario file once here; ScenarioError (one line) if it does not parse.

    Before any variation runs: a file that cannot be read is the command's
    one line and exit status 2, not the same failed verdict for every
    document. ANTLR's own line on stderr is kept out (the error says it).
    """
    logger = _QuietLogger()
    try:
        with contextlib.redirect_stderr(io.StringIO()):
            _parser(logger).process_file(os.path.abspath(scenario_file))
    except Exception as exc:  # scenario_execution's parse errors: ValueError, OSC2Error...
        raise ScenarioError(_line(f'{scenario_file}: parsing failed: {exc}')) from None


def _with_document(task: Task, logger: Any) -> Any:
    """Parse the scenario with one document's overrides (scenario_execution's own path)."""
    with tempfile.NamedTemporaryFile('w', suffix='.yaml', delete=False,
                                     encoding='utf-8') as stream:
        yaml.safe_dump(task.document, stream)
    try:
        return _parser(logger).process_file(task.scenario_file,
                                            scenario_parameter_file=stream.name)
    finally:
        os.unlink(stream.name)


def _line(text: str) -> str:
    return ' '.join(text.split())


def _reason(execution: Any, results: Sequence[Any], logger: _QuietLogger) -> str:
    """
    Return why a run failed, in one line.

    The first failed action's own line if one of ours failed; else the first
    failed behaviour's name and message (a ``timeout`` modifier's); else
    scenario_execution's message.
    """
    from scenario_execution.clock_behaviors import ClockTimeout

    from r2d2_sim.osc.actions import SimAction
    root = execution.current_scenario
    if root is not None:
        behaviours = list(root.iterate())
        for behaviour in behaviours:
            if isinstance(behaviour, SimAction) and behaviour.failure_line:
                return behaviour.failure_line
        for behaviour in behaviours:
            if behaviour.status == Status.FAILURE and behaviour.feedback_message:
                return _line(f'{behaviour.name}: {behaviour.feedback_message}')
            if behaviour.status == Status.FAILURE and isinstance(behaviour, ClockTimeout):
                # scenario_execution's timeout modifier fails without a message.
                return f'timed out after {behaviour._duration:g} s'  # noqa: SLF001
    for result in results:
        if not result.result:
            return _line(result.failure_message)
    return _line(logger.errors[0]) if logger.errors else 'no scenario ran'


def _outcome(simulation: Any, passed: bool, reason: str, wall_s: float
             ) -> Optional[Dict[str, Any]]:
    """Return the farm's Outcome of the run (the simulation's measures, this verdict)."""
    from r2d2_sim.farm.run import Outcome
    measures = simulation.measures() if hasattr(simulation, 'measures') else {}
    if not measures:
        return None
    return Outcome(passed=passed, reason=reason, wall_s=wall_s, **measures).to_dict()


def scenario_parameters(scenario_file: str, document: Optional[Dict[str, Any]] = None
                        ) -> Dict[str, Any]:
    """
    Return the parameters the scenario (with ``document``'s overrides) gives the simulation.

    Those :data:`~r2d2_sim.osc.parameters.DEFAULTS` names: what ``reset``
    receives. With :func:`simulator_parameters`, what to start ``sim_node``
    with so that it stands as the in-process run starts.
    """
    from r2d2_sim.osc.entry_points import ensure_registered
    from r2d2_sim.osc.parameters import DEFAULTS
    ensure_registered()  # osc.r2d2, which the scenario imports, from a source checkout too
    task = Task(os.path.abspath(scenario_file), 0, document)
    logger = _QuietLogger()
    trees = (_parser(logger).process_file(task.scenario_file) if document is None
             else _with_document(task, logger))
    return {name: value for name, value in trees[0][1].items() if name in DEFAULTS}


def simulator_parameters(scenario_file: str, document: Optional[Dict[str, Any]] = None
                         ) -> Dict[str, Any]:
    """Return sim_node's parameters for the scenario: its world, start and seed, as in process."""
    from r2d2_sim.osc.in_process import IN_PROCESS_PARAMETERS
    from r2d2_sim.osc.parameters import read_parameters
    settings = read_parameters(scenario_parameters(scenario_file, document))
    return {**IN_PROCESS_PARAMETERS, **settings.scenario.parameters(), **settings.parameters}


# -- every document, on the farm's executors -------------------------------------------------


@dataclass(frozen=True)
class DocumentsJob:
    """
    A parameter file's documents as a job of the farm's executors: item ``k`` runs task ``k``.

    An :class:`~r2d2_sim.farm.job.ItemJob`: the executors pickle it once
    per worker, which parses the scenario file once (:meth:`prepare`) and
    then runs document after document.
    """

    tasks: Tuple[Task, ...]

    def prepare(self) -> None:
        """Register osc.r2d2 and parse the scenario file, once per worker."""
        from r2d2_sim.osc.entry_points import ensure_registered
        ensure_registered()
        for path in sorted({task.scenario_file for task in self.tasks}):
            if os.path.isfile(path):
                _parsed(path, os.stat(path).st_mtime_ns)

    def run_item(self, item: Any) -> Dict[str, Any]:
        """Run document ``item.key``; return its :class:`Verdict` as a dictionary."""
        return run_document(self.tasks[item.key])._asdict()

    def items(self) -> List[Any]:
        """Return one item per task: its place in the list, and its seed (0 when it has none)."""
        from r2d2_sim.farm.job import Item
        return [Item(index, _seed_of(task)) for index, task in enumerate(self.tasks)]


def _seed_of(task: Task) -> int:
    """Return the seed the task's document gives its scenario (0 when it gives none)."""
    document = task.document or {}
    for values in ([document[task.scenario]] if task.scenario in document
                   else document.values()):
        seed = (values or {}).get('seed')
        if isinstance(seed, int):
            return seed
    return 0


def _verdict_of(task: Task, result: Any) -> Verdict:
    """Return a task's verdict from what the executor gave back (a result or a crash)."""
    from r2d2_sim.farm.executors import Crash
    name = task.name or task.scenario or f'{Path(task.scenario_file).stem}-{task.number}'
    if isinstance(result, Crash):
        return Verdict(task.number, name, False, f'crashed: {result.reason}', 0.0, None)
    if result.outcome is None:
        return Verdict(task.number, name, False, f'the run raised {result.error}',
                       result.task_s, None)
    return Verdict(**result.outcome)


def executor_map(executor: Optional[str] = None, address: Optional[str] = None,
                 workers: Optional[int] = None) -> Mapper:
    """
    Return a map of tasks onto one of the farm's executors (see :mod:`r2d2_sim.farm.executors`).

    ``executor`` (local, ray, dask), ``address`` and ``workers`` as the farm
    runner's command line takes them; ExecutorError (one line) when the
    executor cannot be used. Its function argument is always
    :func:`run_document` (the executors run a :class:`DocumentsJob`).
    """
    def mapped(function: Callable[[Task], Verdict], tasks: Sequence[Task]) -> Iterable[Verdict]:
        from r2d2_sim.farm.executors import choose
        job = DocumentsJob(tuple(tasks))
        pool = choose(executor, address, payload=job, record='none', workers=workers)
        pool.start()
        verdicts: List[Verdict] = []
        try:
            pool.submit(job.items())
            while pool.pending():
                verdicts += [_verdict_of(job.tasks[item.key], result)
                             for item, result in pool.wait(1.0)]
        except BaseException:
            pool.stop()
            raise
        pool.close()
        return verdicts
    return mapped


def run_variations(scenario_file: str, parameter_file: Optional[str], output_dir: str, *,
                   jobs: Optional[int] = None, map_tasks: Optional[Mapper] = None,
                   report: bool = True, simulation: str = IN_PROCESS) -> List[Verdict]:
    """
    Run every scenario of ``scenario_file`` with each document of ``parameter_file``.

    Return the verdicts, one per task (:func:`tasks_of`).
    ``map_tasks(run_document, tasks)`` runs them (default: the farm's local
    executor with ``jobs`` processes, one per core when None; ``jobs`` 1
    runs them here, one after another; :func:`executor_map` for a cluster). Writes
    ``output_dir/test.xml`` (one test case per task, named as
    scenario_execution names them) and, with ``report``, the farm's report
    in ``output_dir/farm``. The verdicts are in the tasks' order (document,
    then scenario), whatever order they ran in. ``simulation``: the class
    each task runs against (module:Class).
    """
    tasks = tasks_of(scenario_file, parameter_file, simulation)
    if map_tasks is None:
        map_tasks = (executor_map('local', workers=jobs) if jobs is None or jobs > 1
                     else (lambda f, ts: [f(t) for t in ts]))
    order = {task.name: index for index, task in enumerate(tasks)}
    verdicts = sorted(map_tasks(run_document, tasks),
                      key=lambda v: (order.get(v.name, len(order)), v.number))
    Path(output_dir).mkdir(parents=True, exist_ok=True)
    write_junit(verdicts, Path(output_dir) / 'test.xml')
    if report:
        from r2d2_sim.farm.report import write_report
        source = Path(scenario_file).name
        # Not `python -m r2d2_sim.farm rerun` (it reruns pytest tests): the documents again.
        again = ['python', '-m', 'r2d2_sim.osc', os.path.abspath(scenario_file)] + (
            ['--parameters', os.path.abspath(parameter_file)] if parameter_file else [])
        records = [{'nodeid': f'{source}::{v.name}', 'outcome': v.outcome,
                    'rerun': f'{shlex.join(again)} --jobs 1 (document {v.number})'}
                   for v in verdicts if v.outcome is not None]
        if records:
            write_report(records, Path(output_dir) / 'farm',
                         invocation_dir=os.getcwd(), picture=True)
    return verdicts


def write_junit(verdicts: Sequence[Verdict], path: Path) -> None:
    """Write one JUnit file: a test case per verdict, as scenario_execution writes them."""
    failures = sum(not v.passed for v in verdicts)
    lines = ['<?xml version="1.0" encoding="utf-8"?>',
             f'<testsuite errors="0" failures="{failures}" name="scenario_execution" '
             f'tests="{len(verdicts)}" time="{sum(v.wall_s for v in verdicts):.6f}">']
    for verdict in verdicts:
        lines.append(f'  <testcase classname="tests.scenario" name={quoteattr(verdict.name)} '
                     f'time="{verdict.wall_s:.6f}">')
        if not verdict.passed:
            lines.append(f'    <failure message={quoteattr(verdict.reason)}/>')
        lines.append('  </testcase>')
    lines.append('</testsuite>')
    path.write_text('\n'.join(lines) + '\n', encoding='utf-8')
