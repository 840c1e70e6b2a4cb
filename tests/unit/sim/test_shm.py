"""Stale Fast DDS shared-memory files are removed; live and fresh ones are kept."""

import mmap
import os
import pathlib
import time

from swarm_common.shm import clean_stale_segments, mapped_shm_files


def _touch(path: pathlib.Path, age_s: float, size: int = 0) -> None:
    path.write_bytes(b'\0' * size)
    then = time.time() - age_s
    os.utime(path, (then, then))


def test_unmapped_old_segments_go_with_their_lock_files(tmp_path):
    for name in ('fastrtps_0123456789abcdef', 'fastrtps_0123456789abcdef_el',
                 'fastrtps_port7411', 'fastrtps_port7411_el', 'sem.fastrtps_port7411_mutex'):
        _touch(tmp_path / name, age_s=600)
    _touch(tmp_path / 'unrelated_file', age_s=600)
    removed = clean_stale_segments(tmp_path, mapped=set())
    assert removed == sorted(['fastrtps_0123456789abcdef', 'fastrtps_0123456789abcdef_el',
                              'fastrtps_port7411', 'fastrtps_port7411_el',
                              'sem.fastrtps_port7411_mutex'])
    assert [p.name for p in tmp_path.iterdir()] == ['unrelated_file']


def test_segments_in_use_or_being_created_are_kept(tmp_path):
    _touch(tmp_path / 'fastrtps_port7413', age_s=600)
    _touch(tmp_path / 'fastrtps_port7413_el', age_s=600)   # lock file of a mapped segment
    _touch(tmp_path / 'fastrtps_feedfacefeedface', age_s=1)  # a participant starting now
    removed = clean_stale_segments(tmp_path, mapped={'fastrtps_port7413'})
    assert removed == []
    assert len(list(tmp_path.iterdir())) == 3


def test_mapped_files_are_read_from_proc():
    """This process maps a /dev/shm file: the scan of /proc/*/maps must see it."""
    shm = pathlib.Path('/dev/shm')
    if not shm.is_dir():
        return
    path = shm / f'fastrtps_swarmtest{os.getpid()}'
    path.write_bytes(b'\0' * 4096)
    try:
        with open(path, 'r+b') as stream, mmap.mmap(stream.fileno(), 4096):
            assert path.name in mapped_shm_files()
            os.utime(path, (time.time() - 600,) * 2)
            assert path.name not in clean_stale_segments(shm)
            assert path.exists()
    finally:
        path.unlink(missing_ok=True)
