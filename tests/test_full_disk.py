"""A disk that fills up: every writer fails with one line and exit status 2, and leaves nothing behind.

The child processes run with a file-size limit (RLIMIT_FSIZE, with SIGXFSZ ignored), so a write past
it fails as a full disk's would (EFBIG for ENOSPC), in Python's writes and in ffmpeg's alike, without
needing a small file system."""

from __future__ import annotations

import resource
import shutil
import signal
import subprocess
import sys

import pytest

LIMIT_BYTES = 16 * 1024


def _limited() -> None:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT_BYTES, LIMIT_BYTES))


@pytest.mark.parametrize("command", [
    ["record", "--preset", "small", "--out", "{out}/rec.h5"],
    ["demo", "--policy", "scripted", "--episodes", "1", "--video", "{out}/demo.mp4"],
    ["learn", "--demos", "{small}", "--out", "{out}/models"],
], ids=["record", "demo-video", "learn"])
def test_a_write_that_does_not_fit_is_one_line_and_leaves_nothing(command, small_recording, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    small = tmp_path / "small.h5"
    shutil.copyfile(small_recording, small)
    args = [a.format(out=out, small=small) for a in command]
    run = subprocess.run([sys.executable, "-m", "hoap_actions", *args], cwd=tmp_path, capture_output=True, text=True,
                         timeout=600, preexec_fn=_limited)
    assert run.returncode == 2, run.stderr[-2000:]
    lines = [line for line in run.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"hoap-actions {command[0]}: error:"), run.stderr[-2000:]
    assert list(out.iterdir()) == []
