"""
A farm as data, and one variation of it as the task an executor runs.

A :class:`FarmJob` is what the runner needs to run a farm anywhere: what
varies (a :class:`~r2d2_sim.farm.scenario.ScenarioSpace`, or a list of
scenarios), the user's controller (``controller(harness, scenario)`` adds
its nodes, as for :func:`~r2d2_sim.farm.run.run_scenario`), the verdict,
the simulated seconds and the simulator's parameters. It travels to the
workers pickled, once per worker, or as a reference its workers import
themselves (:class:`JobSource`: ``path/to/file.py:NAME`` or
``package.module:NAME``, what the command line takes).

:func:`run_variation` is the task: it re-derives its scenario from its seed
(or its index in the list), keeps ROS discovery on its host, runs it in a
simulator of its own on a domain it leases on its host (the harness does),
notes the Fast DDS segments its process holds (:mod:`r2d2_sim.farm.shm`),
and returns a :class:`TaskResult` as plain data: the outcome's JSON, and
for a failure (or every run, with ``record='all'``) the recording's bytes
and their SHA-256, so the file lands on the machine that asked. An
exception raised by the run is returned as the task's error, never raised
into the executor (which might retry it).

Importing this module imports no rclpy or PyBullet (the runner's process
needs neither); :func:`run_variation` does.
"""

from dataclasses import dataclass, field
import functools
import hashlib
import json
import importlib
import importlib.util
import os
from pathlib import Path
import re
import socket
import sys
import tempfile
import time
import traceback
from typing import (Any, Callable, Dict, List, Mapping, NamedTuple, Optional, Protocol, Sequence,
                    Tuple, Union)

from r2d2_sim.farm.scenario import Scenario, ScenarioError, ScenarioSpace
from r2d2_sim.sim.settings.given import checked_parameters

__all__ = ['FarmJob', 'JobSource', 'ItemJob', 'Item', 'TaskResult', 'run_variation',
           'prepare', 'RECORD_MODES', 'describe', 'LOAD_FAILED', 'load_failure']

# What is recorded: a failure's run (run again, recording, as the pytest farm does),
# every run, or nothing.
RECORD_MODES = ('failures', 'all', 'none')


class Item(NamedTuple):
    """One variation: its key in the farm (the seed, or the index in a list) and its seed."""

    key: int
    seed: int


@dataclass(frozen=True)
class FarmJob:
    """
    A farm: what varies, the user's nodes, the verdict, how long, which parameters.

    ``space``: a :class:`ScenarioSpace` (a variation is ``space.draw(seed)``)
    or a sequence of :class:`Scenario` (a variation is one of them, by
    index). ``controller(harness, scenario)`` adds the user's nodes;
    ``verdict(outcome)`` returns why a run failed ('' when it passed; None:
    :func:`~r2d2_sim.farm.run.reached_safely`); ``seconds`` of simulated
    time at most; ``parameters`` for the simulator; ``name`` names the cases
    of its report (``name[seed]``). Everything must pickle (the workers get
    it so), unless it comes by reference (:class:`JobSource`).
    """

    space: Union[ScenarioSpace, Sequence[Scenario]]
    controller: Callable[..., Any]
    seconds: float
    verdict: Optional[Callable[..., str]] = None
    parameters: Mapping[str, Any] = field(default_factory=dict)
    name: str = 'farm'

    def __post_init__(self) -> None:
        if not isinstance(self.space, ScenarioSpace):
            scenarios = tuple(self.space)
            if not all(isinstance(s, Scenario) for s in scenarios):
                raise ScenarioError('a farm varies a ScenarioSpace or a list of Scenarios, got '
                                    f'{type(self.space).__name__}')
            object.__setattr__(self, 'space', scenarios)
        if not callable(self.controller):
            raise ScenarioError(f'the controller must be callable (harness, scenario), got '
                                f'{type(self.controller).__name__}')
        if not (0.0 < float(self.seconds) < float('inf')):
            raise ScenarioError(f'seconds must be > 0 and finite, got {self.seconds}')
        # numpy's numbers made Python's, tuples lists: a farm's identity is JSON, and ROS
        # takes Python's values. A value no ROS parameter holds or a name the simulator
        # does not read is refused here, before anything runs (inside each variation it
        # failed every one of them).
        object.__setattr__(self, 'parameters',
                           checked_parameters(dict(self.parameters), ScenarioError))

    @property
    def listed(self) -> bool:
        """Return True for a list of scenarios (keys are indices), False for a space (seeds)."""
        return not isinstance(self.space, ScenarioSpace)

    def items(self, keys: Sequence[int]) -> List[Item]:
        """Return the variations of ``keys``: seeds of a space, indices of a list."""
        if not self.listed:
            return [Item(int(k), int(k)) for k in keys]
        scenarios: Sequence[Scenario] = self.space  # type: ignore[assignment]
        wrong = [k for k in keys if not 0 <= k < len(scenarios)]
        if wrong:
            raise ScenarioError(f'the farm lists {len(scenarios)} scenarios (0..'
                                f'{len(scenarios) - 1}), not {wrong[0]}')
        return [Item(int(k), scenarios[k].seed) for k in keys]

    def scenario(self, item: Item) -> Scenario:
        """Return the scenario of ``item``: drawn again from its seed, or the listed one."""
        if self.listed:
            return self.space[item.key]  # type: ignore[index]
        return self.space.draw(item.seed)  # type: ignore[union-attr]

    def case_name(self, key: int) -> str:
        """Return the name of a variation in the report: ``name[key]``."""
        return f'{self.name}[{key}]'


def describe(job: FarmJob) -> Dict[str, Any]:
    """Return what identifies a farm, as JSON data: a report directory resumes only its own."""
    if job.listed:
        text = '\n'.join(s.to_json() for s in job.space)  # type: ignore[union-attr]
        space = 'scenarios sha256 ' + hashlib.sha256(text.encode()).hexdigest()
    else:
        space = repr(job.space)
    identity = {'name': job.name, 'space': space, 'controller': _qualified(job.controller),
                'verdict': _qualified(job.verdict) if job.verdict else 'reached_safely',
                'seconds': float(job.seconds),
                'parameters': {k: job.parameters[k] for k in sorted(job.parameters)}}
    # As farm.json keeps it (a tuple comes back a list): compared with it on a resume.
    return json.loads(json.dumps(identity, sort_keys=True))


def _qualified(function: Any) -> str:
    """
    Return what names a controller or verdict the same way in every process.

    A function, class or method: ``module:qualname``. A ``functools.partial``:
    its function's name and its arguments' reprs. Another callable object: its
    class's name and its repr (or, with the default repr, its attributes'
    reprs). Memory addresses (``at 0x7f...``) are left out of every repr: they
    differ in each process, and a resume compares this with the farm.json an
    earlier process wrote.
    """
    if isinstance(function, functools.partial):
        arguments = [_stable_repr(a) for a in function.args] + [
            f'{k}={_stable_repr(v)}' for k, v in sorted(function.keywords.items())]
        return f'{_qualified(function.func)}({", ".join(arguments)})'
    if hasattr(function, '__qualname__'):
        module = getattr(function, '__module__', None) or '?'
        return f'{module}:{function.__qualname__}'
    kind = type(function)
    name = f'{kind.__module__}:{kind.__qualname__}'
    if kind.__repr__ is not object.__repr__:
        return f'{name} {_stable_repr(function)}'
    state = getattr(function, '__dict__', {})
    return name + '(' + ', '.join(f'{k}={_stable_repr(state[k])}' for k in sorted(state)) + ')'


_ADDRESS = re.compile(r' at 0x[0-9a-fA-F]+')


def _stable_repr(value: Any) -> str:
    """Return ``repr(value)`` without memory addresses; a function by its qualified name."""
    if callable(value) and (hasattr(value, '__qualname__')
                            or isinstance(value, functools.partial)):
        return _qualified(value)
    return _ADDRESS.sub('', repr(value))


@dataclass(frozen=True)
class JobSource:
    """
    A :class:`FarmJob` by reference: ``where`` (a ``.py`` file or a module) and its ``name``.

    Workers import it themselves (a file by its absolute path, which must
    exist on their host too; a module from their ``sys.path``), once per
    process. :meth:`parse` reads the command line's ``WHERE:NAME``.
    """

    where: str
    name: str

    @classmethod
    def parse(cls, text: str) -> 'JobSource':
        """Read ``path/to/farm.py:NAME`` or ``package.module:NAME`` (ScenarioError if not)."""
        where, colon, name = text.rpartition(':')
        if not colon or not where or not name.isidentifier():
            raise ScenarioError(f'{text!r}: name the farm as FILE.py:NAME or MODULE:NAME '
                                '(NAME a FarmJob in it)')
        if where.endswith('.py'):
            path = Path(where).resolve()
            if not path.is_file():
                raise ScenarioError(f'{where}: no such file')
            where = str(path)
        return cls(where, name)

    def __str__(self) -> str:
        return f'{self.where}:{self.name}'

    def load(self) -> FarmJob:
        """Import the job (cached per process); ScenarioError in one line if it is none."""
        cached = _LOADED.get(self)
        if cached is not None:
            return cached
        try:
            module = _import(self.where)
        except ScenarioError:
            raise
        except Exception as exc:
            raise ScenarioError(f'{self.where}: importing it raised {type(exc).__name__}: '
                                f'{exc}') from None
        job = getattr(module, self.name, None)
        if not isinstance(job, FarmJob):
            found = 'nothing' if job is None else f'a {type(job).__name__}'
            raise ScenarioError(f'{self}: {found}, not a FarmJob (r2d2_sim.farm.FarmJob)')
        _LOADED[self] = job
        return job


_LOADED: Dict[JobSource, FarmJob] = {}


def _import(where: str) -> Any:
    """Import a module by name, or a file by path under a name made of its path."""
    if not where.endswith('.py'):
        try:
            return importlib.import_module(where)
        except ImportError as exc:
            raise ScenarioError(f'cannot import {where}: {exc}') from None
    path = Path(where)
    if not path.is_file():
        raise ScenarioError(f'{where}: no such file on {socket.gethostname()}')
    # Its folder on the path, as pytest's rootdir-less import does: its own imports work.
    folder = str(path.parent)
    if folder not in sys.path:
        sys.path.insert(0, folder)
    name = 'r2d2_farm_job_' + hashlib.sha256(where.encode()).hexdigest()[:12]
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    sys.modules[name] = module  # pickling by reference finds the module's functions
    try:
        spec.loader.exec_module(module)  # type: ignore[union-attr]
    except BaseException:
        del sys.modules[name]
        raise
    return module


class ItemJob(Protocol):
    """
    A job of another kind the executors run: one item in, its outcome as JSON data out.

    The farm's executors run anything of this shape as they run a
    :class:`FarmJob` (one task per item, crashes reported and never retried,
    discovery kept on the host, Fast DDS segments cleaned): the OpenSCENARIO
    variations (:class:`r2d2_sim.osc.variations.DocumentsJob`) are one.
    """

    def prepare(self) -> None:
        """Import and read what every item needs, once per worker, before the first."""

    def run_item(self, item: Item) -> Dict[str, Any]:
        """Run ``item`` in this process; return its outcome as JSON data."""


def prepare(job: Any) -> Any:
    """Load a worker's job (a :class:`JobSource` imported) and warm it up; return it."""
    if isinstance(job, JobSource):
        job = job.load()
    if isinstance(job, FarmJob):
        import r2d2_sim.farm.run  # noqa: F401  (rclpy and PyBullet, once, before the first task)
    else:
        job.prepare()
    return job


class TaskResult(NamedTuple):
    """
    What a task sends back, plain data only.

    ``outcome`` is :meth:`Outcome.to_dict` (None when the task raised:
    ``error`` says what, in one line, ``trace`` the traceback);
    ``recording`` the MCAP bytes kept (a failure's, or every run's with
    ``record='all'``) and ``recording_sha256`` their hash; ``host`` and
    ``pid`` where it ran; ``task_s`` its wall time inside the worker.
    ``setup_error`` is set, in one line, when the worker could not load the
    job (import the farm, or the simulator's packages) before the variation
    began: that says nothing of the variation, and stops the run
    (:data:`LOAD_FAILED` starts it).
    """

    key: int
    seed: int
    outcome: Optional[Dict[str, Any]]
    error: Optional[str]
    trace: Optional[str]
    recording: Optional[bytes]
    recording_sha256: Optional[str]
    host: str
    pid: int
    task_s: float
    setup_error: Optional[str] = None


# How a worker that could not load the job says so: the runner stops the run with it,
# as the local pool does (a load failure is no variation's verdict).
LOAD_FAILED = 'a worker could not load the farm'


def run_variation(job: Union[FarmJob, JobSource, ItemJob], item: Item, record: str = 'failures'
                  ) -> TaskResult:
    """
    Run one variation of ``job`` in this process; return its result (see the module).

    An :class:`ItemJob` runs its item itself (``record`` is a FarmJob's only).
    """
    started = time.perf_counter()
    # Discovery stays on this host whatever the worker's environment says; the
    # simulator leases its domain on this host (lock files and domain_coordinator's port).
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    from r2d2_sim.farm import shm
    shm.clean_dead()
    outcome = error = trace = recording = digest = None
    try:
        if isinstance(job, JobSource):
            job = job.load()
        if isinstance(job, FarmJob):
            import r2d2_sim.farm.run  # noqa: F401  (rclpy and PyBullet: a worker's set-up)
    except Exception as exc:  # set-up, not the variation: the runner stops the run
        host = socket.gethostname()
        return TaskResult(item.key, item.seed, None, None, traceback.format_exc(), None, None,
                          host, os.getpid(), time.perf_counter() - started,
                          f'{LOAD_FAILED} on {host}: {_said(exc)}'.splitlines()[0])
    try:
        if isinstance(job, FarmJob):
            with shm.noting():  # the ports Fast DDS opens later, should this process be killed
                outcome, recording = _run(job, item, record, shm)
        else:
            outcome = job.run_item(item)
        if recording is not None:
            digest = hashlib.sha256(recording).hexdigest()
    except Exception as exc:  # the variation's error, reported as its case: never retried
        error = f'{type(exc).__name__}: {exc}'.splitlines()[0]
        trace = traceback.format_exc()
    finally:
        shm.forget()
    return TaskResult(item.key, item.seed, outcome, error, trace, recording, digest,
                      socket.gethostname(), os.getpid(), time.perf_counter() - started)


def _said(exc: BaseException) -> str:
    """Return an exception in words: a ScenarioError's own, another's with its type."""
    return str(exc) if isinstance(exc, ScenarioError) else f'{type(exc).__name__}: {exc}'


def load_failure(record: Dict[str, Any]) -> bool:
    """
    Return True for a record of a variation that never began: its worker could not load the job.

    Such records are no verdict (and the runner writes none); a runner before
    0.2.0 wrote them as crashes that raised the load's ScenarioError
    (``importing it raised``, ``cannot import``, ``no such file on``, ``not a
    FarmJob``): a resume runs those variations again.
    """
    crashed = record.get('crashed') or {}
    reason = str(crashed.get('reason', ''))
    if crashed.get('setup') or LOAD_FAILED in reason:
        return True
    return reason.startswith('raised ScenarioError: ') and any(
        marker in reason for marker in (': importing it raised ', ': cannot import ',
                                        ': no such file on ', ', not a FarmJob ('))


def _run(job: FarmJob, item: Item, record: str,
         shm: Any) -> Tuple[Dict[str, Any], Optional[bytes]]:
    """Run the variation; return its outcome's data and the recording's bytes kept (or None)."""
    from r2d2_sim.farm.run import reached_safely, run_scenario
    scenario = job.scenario(item)
    controller = job.controller

    def noted(harness: Any, scenario: Scenario) -> Any:
        shm.note()  # the simulator's participant exists: its segments are ours
        try:
            return controller(harness, scenario)
        finally:
            shm.note()  # and what the user's nodes added

    with tempfile.TemporaryDirectory(prefix='r2d2_farm_task_') as scratch:
        path = os.path.join(scratch, 'run.mcap')
        outcome = run_scenario(
            scenario, noted, seconds=job.seconds, parameters=job.parameters,
            verdict=job.verdict or reached_safely,
            record=path if record == 'all' else None,
            record_failure=path if record == 'failures' else None)
        kept = None
        if outcome.recording is not None and os.path.exists(path):
            with open(path, 'rb') as source:
                kept = source.read()
        data = outcome.to_dict()
        data['recording'] = None  # the path was the worker's: the runner names its own
        return data, kept
