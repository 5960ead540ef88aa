"""Output that cannot be written: one line naming the file and the cause, exit 2, nothing
half-written left behind (a full file system, a full standard output)."""

from __future__ import annotations

import os
import shutil
import subprocess

import pytest


@pytest.fixture
def full_disk(tmp_path, child):
    """A 64 KiB tmpfs: room for a directory, not for a run's results. Mounting needs root and
    a kernel that lets this process do it; elsewhere the test is skipped, saying why."""
    mnt = tmp_path / "small"
    mnt.mkdir()
    mount = shutil.which("mount")
    r = child.program(mount or "mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", mnt)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here ({r.stderr.strip() or r.returncode})")
    yield mnt
    child.program("umount", mnt)


def test_a_run_onto_a_full_disk_says_so_in_one_line_and_leaves_nothing(full_disk, child):
    out = full_disk / "out"
    r = child.crosscheck("run", "pendulum_xy", "--engines", "mujoco", "--out", out)
    assert r.returncode == 2, r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "No space left on device" in lines[0], r.stderr
    assert str(out / "results.json") in lines[0] or "cannot write" in lines[0]
    assert "Traceback" not in r.stderr
    assert not [p for p in out.rglob("*") if p.is_file()] if out.exists() else True


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full (Linux)")
@pytest.mark.parametrize("argv", [["models"], ["models", "--json"], ["engines"]])
def test_a_full_standard_output_is_one_line_and_exit_2(child, argv):
    with open("/dev/full", "w") as full:
        r = child.crosscheck(*argv, stdout=full, stderr=subprocess.PIPE)
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "No space left on device" in r.stderr, r.stderr
