"""
r2d2_sim.files: regular files read without blocking, directories only we may write.

No ROS, no physics. What every reader of a world's files and every cache
relies on: a FIFO, a device or a directory is refused at once (never waited
on), a file is read to its bound and no further, and a directory or file that
is a link, another user's or writable by others is refused in one line.
"""

import errno
import os
import stat
import threading

import pytest

from r2d2_sim.files import (
    check_private, make_private_directories, open_private_directory, read_regular, UnsafeFile)


def test_a_regular_file_is_read_to_its_bound_and_no_further(tmp_path):
    path = tmp_path / 'mesh.stl'
    path.write_bytes(b'x' * 100)
    assert read_regular(str(path), 100) == b'x' * 100
    with pytest.raises(UnsafeFile) as refused:
        read_regular(str(path), 99)
    assert refused.value.errno == errno.EFBIG and '99 bytes' in refused.value.strerror
    with pytest.raises(FileNotFoundError):
        read_regular(str(tmp_path / 'none.stl'), 100)


def test_a_fifo_a_device_and_a_directory_are_refused_without_waiting(tmp_path):
    fifo = tmp_path / 'fifo.stl'
    os.mkfifo(fifo)
    for path, kind in ((fifo, 'special file'), ('/dev/zero', 'special file'),
                       (tmp_path, 'directory')):
        done = []
        thread = threading.Thread(target=lambda: done.append(_refusal(path)), daemon=True)
        thread.start()
        thread.join(5.0)  # a read that blocked would still be waiting; not a measure of speed
        if thread.is_alive():
            os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
            pytest.fail(f'reading {path} blocked')
        assert kind in done[0] and 'not a regular file' in done[0]


def _refusal(path):
    with pytest.raises(UnsafeFile) as refused:
        read_regular(str(path), 1 << 20)
    return refused.value.strerror


def test_a_private_directory_is_created_0700_and_checked(tmp_path):
    path = str(tmp_path / 'cache' / 'r2d2_sim')
    os.close(open_private_directory(path))
    assert stat.S_IMODE(os.lstat(path).st_mode) == 0o700
    deepest = make_private_directories(path, 'meshes', 'ab')
    assert deepest == os.path.join(path, 'meshes', 'ab')
    assert stat.S_IMODE(os.lstat(deepest).st_mode) == 0o700
    check_private(deepest)


@pytest.mark.parametrize('make_it, problem', [
    (lambda p: (os.mkdir(p), os.chmod(p, 0o777)), 'writable by others (mode 777)'),
    (lambda p: (os.mkdir(p), os.chmod(p, 0o770)), 'writable by others (mode 770)'),
    (lambda p: os.symlink('/tmp', p), 'a symbolic link'),
    (lambda p: open(p, 'w').close(), 'a plain file, not a directory'),
], ids=['world-writable', 'group-writable', 'a link', 'a file'])
def test_a_directory_others_could_write_or_swap_is_refused_in_one_line(tmp_path, make_it,
                                                                       problem):
    path = str(tmp_path / 'shared')
    make_it(path)
    for check in (lambda: check_private(path), lambda: open_private_directory(path),
                  lambda: make_private_directories(str(tmp_path), 'shared')):
        with pytest.raises(UnsafeFile) as refused:
            check()
        assert problem in refused.value.strerror and path in refused.value.strerror
        assert '\n' not in refused.value.strerror


def test_a_file_must_be_a_plain_file_of_ours_that_others_cannot_write(tmp_path):
    path = tmp_path / 'info.json'
    path.write_text('{}')
    os.chmod(path, 0o600)
    check_private(str(path), directory=False)
    os.chmod(path, 0o666)
    with pytest.raises(UnsafeFile, match='writable by others'):
        check_private(str(path), directory=False)
