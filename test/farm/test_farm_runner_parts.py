"""
The farm runner's parts that start no process: shards, seeds, jobs, progress, crashes, segments.

The runner itself, with its worker processes and clusters, is tested in
``test/system/test_farm_runner.py`` and ``test/system/test_farm_clusters.py``.
"""

import fcntl
import io
import json
import os
from pathlib import Path
import pickle
import threading
import uuid

import pytest

from r2d2_sim.farm import shm
from r2d2_sim.farm.executors import choose, ExecutorError
from r2d2_sim.farm.executors.base import check_reachable
from r2d2_sim.farm.job import describe, FarmJob, Item, JobSource
from r2d2_sim.farm.progress import Progress
from r2d2_sim.farm.report import write_report
from r2d2_sim.farm.runner import FarmError, parse_seeds, run_farm
from r2d2_sim.farm.scenario import Scenario, ScenarioError, ScenarioSpace
from r2d2_sim.farm.shards import parse_shard, Shard, shard_of


def drive(harness, scenario):
    """Command nothing (these tests never run the controller)."""


SPACE = ScenarioSpace(obstacles=(0, 2))
JOB = FarmJob(SPACE, drive, seconds=1.0, name='idle')


# -- shards --------------------------------------------------------------------------

def test_a_shard_is_read_as_i_of_n_counted_from_one():
    assert parse_shard('1/4') == Shard(1, 4) and str(parse_shard('4/4')) == '4/4'


@pytest.mark.parametrize('text, says', [
    ('3/2', 'i must be 1..N'), ('0/2', 'i must be 1..N'), ('1/0', 'N must be 1 or more'),
    ('a/b', 'write it i/N'), ('2', 'write it i/N'), ('1/2/3', 'write it i/N')])
def test_a_shard_that_cannot_be_is_one_line(text, says):
    with pytest.raises(ValueError) as raised:
        parse_shard(text)
    assert says in str(raised.value) and '\n' not in str(raised.value)


def test_shards_split_the_seeds_between_them_once_each_by_the_seed_alone():
    seeds = range(1000)
    shards = [Shard(i, 4) for i in range(1, 5)]
    owners = [[s for s in shards if s.holds(seed)] for seed in seeds]
    assert all(len(owner) == 1 for owner in owners)
    sizes = [sum(s.holds(seed) for seed in seeds) for s in shards]
    assert min(sizes) > 200  # about 250 each
    # Pinned: a seed's shard is SHA-256 of its decimal text, whatever else runs.
    assert [shard_of(seed, 4) for seed in range(8)] == [shard_of(s, 4) for s in range(8)]
    assert shard_of(0, 1) == 1
    evens = [shard_of(seed, 2) for seed in range(0, 200, 2)]
    assert set(evens) == {1, 2}  # a hash, not seed % N: every even seed is not in one shard


# -- seeds and the job ---------------------------------------------------------------

def test_seeds_are_read_as_ranges_and_lists():
    assert parse_seeds('0-3,7,9-10') == [0, 1, 2, 3, 7, 9, 10]
    for wrong in ('3-1', 'x', '-2', '1,,2'):
        with pytest.raises(ValueError, match='--seeds'):
            parse_seeds(wrong)


def test_a_job_derives_each_variation_from_its_seed_or_its_index():
    assert JOB.items([3, 5]) == [Item(3, 3), Item(5, 5)]
    assert JOB.scenario(Item(3, 3)) == SPACE.draw(3)
    listed = FarmJob([SPACE.draw(7), SPACE.draw(9)], drive, seconds=1.0)
    assert listed.items([1]) == [Item(1, 9)] and listed.scenario(Item(1, 9)) == SPACE.draw(9)
    with pytest.raises(ScenarioError, match='lists 2 scenarios'):
        listed.items([2])
    assert pickle.loads(pickle.dumps(JOB)) == JOB


def test_a_job_that_cannot_be_is_one_line():
    with pytest.raises(ScenarioError, match='ScenarioSpace or a list'):
        FarmJob(['not a scenario'], drive, seconds=1.0)
    with pytest.raises(ScenarioError, match='callable'):
        FarmJob(SPACE, 'drive', seconds=1.0)
    with pytest.raises(ScenarioError, match='seconds'):
        FarmJob(SPACE, drive, seconds=0.0)


def test_a_job_is_identified_by_what_it_runs_not_by_how_many():
    identity = describe(JOB)
    assert identity == describe(FarmJob(SPACE, drive, seconds=1.0, name='idle'))
    assert identity['controller'].endswith(':drive')
    assert describe(FarmJob(SPACE, drive, seconds=2.0, name='idle')) != identity
    json.dumps(identity)


def test_a_job_with_tuples_in_its_parameters_is_its_own_farm_once_saved():
    """farm.json keeps a tuple as a list: a resume compares what it kept with this."""
    job = FarmJob(SPACE, drive, seconds=1.0, name='idle',
                  parameters={'initial_pose': (0.0, 0.0, 0.0)})
    saved = json.loads(json.dumps({'farm': describe(job)}))['farm']
    assert saved == describe(job) and saved['parameters']['initial_pose'] == [0.0, 0.0, 0.0]


def test_a_job_by_reference_is_loaded_from_a_file(tmp_path):
    farm = tmp_path / 'my_farm.py'
    farm.write_text('from r2d2_sim.farm import FarmJob, ScenarioSpace\n'
                    'def drive(harness, scenario):\n    pass\n'
                    'FARM = FarmJob(ScenarioSpace(), drive, seconds=2.0, name="mine")\n'
                    'OTHER = 3\n', encoding='utf-8')
    source = JobSource.parse(f'{farm}:FARM')
    assert source.load().name == 'mine' and source.load() is source.load()
    assert pickle.loads(pickle.dumps(source)) == source
    with pytest.raises(ScenarioError, match='not a FarmJob'):
        JobSource.parse(f'{farm}:OTHER').load()
    with pytest.raises(ScenarioError, match='no such file'):
        JobSource.parse(f'{tmp_path}/missing.py:FARM')
    with pytest.raises(ScenarioError, match='FILE.py:NAME'):
        JobSource.parse(str(farm))
    with pytest.raises(ScenarioError, match='cannot import'):
        JobSource.parse('no_such_module_here:FARM').load()


# -- choosing an executor, bad input ---------------------------------------------------

def test_the_executor_is_local_unless_a_cluster_is_named(monkeypatch):
    monkeypatch.delenv('RAY_ADDRESS', raising=False)
    monkeypatch.delenv('DASK_SCHEDULER_ADDRESS', raising=False)
    assert choose(None, None, payload=JOB, record='failures', workers=1).name == 'local'
    with pytest.raises(ExecutorError, match='--executor ray or --executor dask'):
        choose(None, 'somehost:1234', payload=JOB, record='failures', workers=1)
    with pytest.raises(ExecutorError, match='takes no address'):
        choose('local', 'tcp://x:1', payload=JOB, record='failures', workers=1)
    with pytest.raises(ExecutorError, match='one of local, ray, dask'):
        choose('slurm', None, payload=JOB, record='failures', workers=1)
    for name, workers in (('local', 0), ('local', -3), ('ray', 0), ('dask', 0)):
        with pytest.raises(ExecutorError, match=f'^--workers {workers}: at least 1$'):
            choose(name, None, payload=JOB, record='failures', workers=workers)


def test_an_unreachable_address_is_one_line():
    with pytest.raises(ExecutorError) as raised:
        check_reachable('tcp://127.0.0.1:9', 'Dask scheduler', 8786)
    assert 'cannot reach the Dask scheduler at tcp://127.0.0.1:9' in str(raised.value)
    assert '\n' not in str(raised.value)


def test_a_farm_that_does_not_pickle_is_one_line_before_anything_runs(tmp_path):
    job = FarmJob(SPACE, lambda harness, scenario: None, seconds=1.0)
    with pytest.raises(FarmError) as raised:
        run_farm(job, variations=2, out=tmp_path / 'report', executor='local', progress=False)
    assert 'does not pickle' in str(raised.value) and '\n' not in str(raised.value)
    assert not list((tmp_path / 'report').glob('outcomes/*'))


class UnpicklableSpace(ScenarioSpace):
    """A space that holds an open file: it cannot travel to a worker."""

    def __init__(self) -> None:
        super().__init__()
        object.__setattr__(self, 'log', open(os.devnull, 'w'))


def test_a_space_that_does_not_pickle_is_one_line(tmp_path):
    job = FarmJob(UnpicklableSpace(), drive, seconds=1.0)
    with pytest.raises(FarmError, match='does not pickle') as raised:
        run_farm(job, variations=1, out=tmp_path, executor='local', progress=False)
    assert '\n' not in str(raised.value)
    job.space.log.close()


def test_a_report_directory_that_cannot_be_written_is_one_line(tmp_path):
    blocker = tmp_path / 'a_file'
    blocker.write_text('')
    with pytest.raises(FarmError) as raised:
        run_farm(JOB, variations=1, out=blocker / 'report', progress=False)
    assert 'cannot be written' in str(raised.value) and '\n' not in str(raised.value)


def test_a_directory_of_another_farm_is_not_resumed(tmp_path):
    (tmp_path / 'farm.json').write_text(json.dumps({'farm': describe(JOB)}))
    other = FarmJob(SPACE, drive, seconds=5.0, name='idle')
    with pytest.raises(FarmError, match='another farm \\(its seconds differs\\)'):
        run_farm(other, variations=1, out=tmp_path, progress=False)


# -- progress ------------------------------------------------------------------------

def test_progress_counts_and_says_the_time_left():
    stream = io.StringIO()
    progress = Progress(10, done=2, stream=stream, live=False)
    for verdict in ('passed', 'failed', 'crashed'):
        progress.add(verdict)
    line = progress.line()
    assert '5/10: 1 passed, 1 failed, 1 crashed' in line and 'left' in line
    assert stream.getvalue().count('\n') == 3  # every tenth of 10 is every variation
    quiet = Progress(10, stream=io.StringIO(), enabled=False)
    quiet.add('passed')
    assert quiet.stream.getvalue() == ''


# -- a report with crashes -------------------------------------------------------------

def outcome_of(seed: int, passed: bool = True) -> dict:
    """Return an outcome's JSON for the report, as a run gives it."""
    return {'scenario': Scenario(seed=seed).to_dict(), 'passed': passed,
            'reason': '' if passed else 'touched box_0 at 1.000 s (base, 3 N)', 'seconds': 5.0,
            'time_to_goal_s': 2.5 if passed else None, 'clearance_m': 0.2, 'closest': 'box_0',
            'closest_s': 1.0, 'contacts': [], 'tipped_s': None,
            'trajectory': [[0, 0.0, 0.0, 0.0], [10**8, 0.1, 0.0, 0.0]], 'steps': 600,
            'wall_s': 0.5, 'recording': None}


def test_a_crashed_variation_is_a_case_of_its_own_with_its_seed(tmp_path):
    farm = {'rerun': 'python -m r2d2_sim.farm run f.py:FARM --seeds 7', 'seed': 7, 'key': 7}
    records = [
        {'nodeid': 'f[3]', 'run': 0, 'property': False, 'outcome': outcome_of(3)},
        {'nodeid': 'f[5]', 'run': 0, 'property': False, 'outcome': outcome_of(5, False)},
        {'nodeid': 'f[7]', 'run': 0, 'property': False, 'outcome': None, 'worker': 'h:42',
         'farm': farm, 'crashed': {'reason': 'crashed: its worker process 42 died, killed by '
                                   'SIGKILL', 'host': 'h', 'pid': 42}}]
    written = write_report(records, tmp_path, picture=True)
    data = json.loads(written['report.json'].read_text())
    assert data['summary']['crashed'] == 1 and data['summary']['failed'] == 1
    assert data['summary']['runs'] == 3 and data['summary']['clearance_m']['runs'] == 2
    crashed = data['cases'][2]
    assert crashed['crashed'] and crashed['seed'] == 7 and 'SIGKILL' in crashed['reason']
    text = written['report.md'].read_text()
    assert '## Crashed (1)' in text and 'seed 7' in text and '--case 2' in text
    assert '| crashed (no verdict' in text and '## Failures (1)' in text


def test_a_dask_task_the_scheduler_dropped_is_a_crash_not_an_error(monkeypatch):
    """Dask's wait raises for a cancelled future (ci: "already forgotten", worker killed)."""
    import distributed
    from distributed.client import FuturesCancelledError
    from r2d2_sim.farm.executors.dask_cluster import take_finished

    class Dropped:
        status = 'cancelled'

    class Running:
        status = 'pending'

    def wait(futures, timeout, return_when):
        raise FuturesCancelledError([])
    monkeypatch.setattr(distributed, 'wait', wait)
    dropped, running = Dropped(), Running()
    pending = {dropped: Item(5, 5), running: Item(6, 6)}
    (item, crash), = take_finished(pending, 0.1)
    assert item == Item(5, 5) and crash.key == 5 and crash.seed == 5
    assert 'died' in crash.reason and 'cancelled' in crash.reason
    assert list(pending) == [running]


# -- shared-memory segments ------------------------------------------------------------

def fake_segment(tmp_name: str) -> Path:
    """Make a file in /dev/shm named as Fast DDS names its segments (removed by the test)."""
    path = shm.SHM_DIR / tmp_name
    path.write_bytes(b'')
    return path


@pytest.fixture
def registry(tmp_path, monkeypatch):
    """Give the test a registry of task notes of its own: other tests' sweeps stay out."""
    path = tmp_path / 'tasks'
    path.mkdir()
    monkeypatch.setattr(shm, 'registry_dir', lambda: path)
    return path


def test_only_the_segments_of_dead_tasks_that_nobody_uses_are_removed(registry):
    tag = uuid.uuid4().hex[:12]
    dead_only = fake_segment(f'fastrtps_{tag}a')
    used = fake_segment(f'fastrtps_{tag}b')
    live_task = fake_segment(f'fastrtps_{tag}c')
    not_fast_dds = fake_segment(f'other_{tag}')
    me = os.getpid()
    start = shm._start_time(me)
    # A dead task: this process's id with another start time (an id reused by another process).
    (registry / f'{me}-0').write_text('\n'.join([dead_only.name, used.name, not_fast_dds.name,
                                                 '../etc/passwd']))
    (registry / f'{me}-{start}').write_text(live_task.name)
    holder = open(used, 'rb')  # a live process holds it open
    try:
        removed = shm.clean_dead()
        assert dead_only.name in removed and not dead_only.exists()
        assert used.exists() and live_task.exists() and not_fast_dds.exists()
        assert (registry / f'{me}-{start}').exists()
        # The segment still in use stays noted, and nothing else of the dead task's.
        assert (registry / f'{me}-0').read_text().split() == [used.name]
        holder.close()  # the other process lets go of it (without removing it)
        assert shm.clean_dead() == [used.name] and not used.exists()
        assert not (registry / f'{me}-0').exists() and live_task.exists()
    finally:
        holder.close()
        (registry / f'{me}-0').unlink(missing_ok=True)
        (registry / f'{me}-{start}').unlink(missing_ok=True)
        for path in (dead_only, used, live_task, not_fast_dds):
            path.unlink(missing_ok=True)


def test_a_dead_owners_segment_goes_though_a_sender_maps_it_and_a_new_owners_stays(registry):
    """
    A port the dead task owned, its lock free, goes though a sender still maps it.

    What stays: one a new owner locked, one a new owner made again (another
    inode) and has not locked yet, one the task only read from (shared, no lock).
    """
    tag = uuid.uuid4().hex[:12]
    digits = tag[:4].translate(str.maketrans('abcdef', '123456'))
    zombie, relocked, remade, shared = (fake_segment(f'fastrtps_port8{digits}{n}')
                                        for n in '0123')
    ports = [zombie, relocked, remade, shared]
    files = ports + [fake_segment(f'{p.name}_el') for p in ports] + [
        fake_segment(f'sem.{p.name}_mutex') for p in ports]
    inode = {p.name: os.stat(p).st_ino for p in ports}
    note = registry / f'{os.getpid()}-0'  # a dead task
    owned = {zombie.name: inode[zombie.name], relocked.name: inode[relocked.name],
             remade.name: inode[remade.name] + 1}  # remade: not the file the task owned
    note.write_text('\n'.join(f'{p.name} {owned[p.name]}' if p.name in owned else p.name
                              for p in files))
    users = [open(p, 'rb') for p in ports]  # live senders (or readers) map every port
    users += [open(shm.SHM_DIR / f'sem.{p.name}_mutex', 'rb') for p in (relocked, remade)]
    owner = open(shm.SHM_DIR / f'{relocked.name}_el', 'rb')
    fcntl.flock(owner, fcntl.LOCK_EX)  # a new participant listens on relocked
    try:
        removed = shm.clean_dead()
        # The zombie and its companions; the others stay whole, lock files and semaphores too.
        assert sorted(removed) == sorted([zombie.name, f'{zombie.name}_el',
                                          f'sem.{zombie.name}_mutex'])
        assert not zombie.exists() and relocked.exists() and remade.exists() and shared.exists()
        kept = [name for p in (relocked, remade, shared)
                for name in (p.name, f'{p.name}_el', f'sem.{p.name}_mutex')]
        assert sorted(line.split()[0] for line in note.read_text().splitlines()) == sorted(kept)
        owner.close()  # the new owner is killed too: its lock goes with it
        for user in users:
            user.close()  # and everyone lets go
        assert sorted(shm.clean_dead()) == sorted(kept)
        assert not note.exists()
    finally:
        for handle in users + [owner]:
            handle.close()
        note.unlink(missing_ok=True)
        for path in files:
            path.unlink(missing_ok=True)


def test_a_port_made_again_while_the_sweep_looks_is_not_removed(monkeypatch, registry):
    """A dead task's free port that a new participant makes anew during the scan stays."""
    port = fake_segment(f'fastrtps_port6{uuid.uuid4().int % 10**6}')
    note = registry / f'{os.getpid()}-0'  # a dead task
    note.write_text(port.name)
    scan = shm.in_use

    def made_again_meanwhile(names):
        port.unlink()
        port.write_bytes(b'new')  # another file under the same name (another inode)
        return scan(names)
    monkeypatch.setattr(shm, 'in_use', made_again_meanwhile)
    try:
        assert shm.clean_dead() == [] and port.read_bytes() == b'new'
        assert not note.exists()  # the file there now is not the task's
    finally:
        note.unlink(missing_ok=True)
        port.unlink(missing_ok=True)


def test_a_segment_nobody_maps_stays_while_an_owner_holds_its_lock(registry):
    """An owner may hold the lock before it maps the port (Fast DDS opens it so)."""
    port = fake_segment(f'fastrtps_port5{uuid.uuid4().int % 10**6}')
    lock = fake_segment(f'{port.name}_el')
    note = registry / f'{os.getpid()}-0'  # a dead task
    note.write_text(f'{port.name}\n{lock.name}\n')
    owner = open(lock, 'rb')
    fcntl.flock(owner, fcntl.LOCK_EX)
    try:
        assert shm.clean_dead() == [] and port.exists() and lock.exists()
        assert note.read_text().split() == [port.name, lock.name]
        owner.close()  # the owner died without removing its port: a zombie now
        assert sorted(shm.clean_dead()) == sorted([port.name, lock.name])
        assert not note.exists()
    finally:
        owner.close()
        note.unlink(missing_ok=True)
        port.unlink(missing_ok=True)
        lock.unlink(missing_ok=True)


def test_a_sweep_never_raises_on_what_it_cannot_read(registry):
    """A note that is not text is left alone; a writer killed mid-note leaves no scratch."""
    port = fake_segment(f'fastrtps_port3{uuid.uuid4().int % 10**6}')
    (registry / f'{os.getpid()}-0').write_bytes(b'\xff\xfe not a note')
    (registry / f'{os.getpid()}-1').write_text(f'{port.name} {os.stat(port).st_ino}\n')
    dead_writer = registry / f'{os.getpid()}-2.{2 ** 22 + 1}.new'  # beyond pid_max
    dead_writer.write_text('half a note')
    try:
        assert shm.clean_dead() == [port.name] and not port.exists()
        assert not dead_writer.exists()  # the scratch file of a writer that is gone
        assert (registry / f'{os.getpid()}-0').exists()  # not a note: left as it is
        assert not (registry / f'{os.getpid()}-1').exists()
    finally:
        for path in [port] + list(registry.iterdir()):
            path.unlink(missing_ok=True)


def test_sweeps_at_once_never_fail_and_keep_what_is_used(registry):
    """Tasks that start together each sweep (ci: one's rewrite of a note crashed another's)."""
    tag = uuid.uuid4().hex[:8]
    used = [fake_segment(f'fastrtps_{tag}u{n}') for n in range(40)]
    free = [fake_segment(f'fastrtps_{tag}f{n}') for n in range(40)]
    notes = [registry / f'{os.getpid()}-{n}' for n in range(40)]  # dead tasks
    for note, one, other in zip(notes, used, free):
        note.write_text(f'{one.name}\n{other.name}\n')
    holders = [open(path, 'rb') for path in used]  # live senders map these
    errors: list = []
    removed: list = []

    def sweep():
        try:
            removed.extend(shm.clean_dead())
        except Exception as error:  # noqa: B902 (the test reports any)
            errors.append(error)
    threads = [threading.Thread(target=sweep) for _ in range(6)]
    try:
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        assert errors == []
        assert sorted(name for name in removed if tag in name) == sorted(p.name for p in free)
        assert all(path.exists() for path in used)
        assert [note.read_text().split() for note in notes] == [[p.name] for p in used]
    finally:
        for handle in holders:
            handle.close()
        for path in notes + used + free:
            path.unlink(missing_ok=True)


def test_a_sweep_scans_the_processes_once_for_every_dead_task(monkeypatch, registry):
    """The sweep's lock is held for one scan of /proc, however many tasks died."""
    tag = uuid.uuid4().hex[:8]
    files = [fake_segment(f'fastrtps_{tag}s{n}') for n in range(5)]
    notes = [registry / f'{os.getpid()}-{n}' for n in range(5)]  # dead tasks
    for note, path in zip(notes, files):
        note.write_text(path.name)
    scans = []
    scan = shm.in_use
    monkeypatch.setattr(shm, 'in_use', lambda names: scans.append(names) or scan(names))
    try:
        # (Another test's dead task, under xdist, may be swept too.)
        assert {path.name for path in files} <= set(shm.clean_dead())
        assert len(scans) == 1 and {path.name for path in files} <= scans[0]
        assert not any(note.exists() for note in notes)
    finally:
        for path in notes + files:
            path.unlink(missing_ok=True)


def test_a_task_notes_the_inode_of_each_segment_it_owns(registry):
    tag = uuid.uuid4().hex[:12]
    digits = tag[:4].translate(str.maketrans('abcdef', '123456'))
    mine, theirs = (fake_segment(f'fastrtps_port7{digits}{n}') for n in '01')
    locks = [fake_segment(f'{p.name}_el') for p in (mine, theirs)]
    handles = [open(mine, 'rb'), open(theirs, 'rb'), open(locks[0], 'rb')]
    fcntl.flock(handles[2], fcntl.LOCK_EX)  # this process owns the first port
    try:
        shm.note()
        noted = shm._read_note(shm._note_path(os.getpid()))
        assert noted[mine.name] == os.stat(mine).st_ino
        assert noted[theirs.name] is None and noted[f'{mine.name}_el'] is None
    finally:
        for handle in handles:
            handle.close()
        shm.forget()
        for path in [mine, theirs] + locks:
            path.unlink(missing_ok=True)


def test_a_task_notes_its_segments_with_their_lock_files_and_forgets_them(registry):
    tag = uuid.uuid4().hex[:12]
    port = fake_segment(f'fastrtps_port9{tag[:4].translate(str.maketrans("abcdef", "123456"))}')
    with open(port, 'rb'):
        shm.note()
        noted = shm._note_path(os.getpid()).read_text().split()
    try:
        assert port.name in noted and port.name + '_el' in noted
        assert f'sem.{port.name}_mutex' in noted
    finally:
        shm.forget()
        port.unlink()
    assert not shm._note_path(os.getpid()).exists()


def test_a_dask_task_that_could_not_unpickle_its_job_stops_the_run(monkeypatch):
    """run_once returns the variation's errors: an ImportError of the task is the set-up's."""
    import distributed
    from r2d2_sim.farm.executors.dask_cluster import take_finished

    class Erred:
        status = 'error'

        def exception(self):
            return ModuleNotFoundError("No module named 'farms'")
    monkeypatch.setattr(distributed, 'wait', lambda futures, timeout, return_when: None)
    with pytest.raises(ExecutorError, match="could not load the farm: ModuleNotFoundError"):
        take_finished({Erred(): Item(3, 3)}, 0.1)
