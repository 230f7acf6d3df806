"""Videos written and then checked: ffmpeg reports a full disk in its own output, not by failing the
call, so a video counts as written only once its frames are read back."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from hoap_actions.errors import OutputPathError

__all__ = ["write_video"]


def write_video(path: str | os.PathLike, frames: Sequence[np.ndarray], fps: float) -> None:
    """Encode ``frames`` (H, W, 3) uint8 to an H.264 mp4 at ``path`` (a claimed partial) and check that
    all of them can be read back; else :class:`OutputPathError` naming the file."""
    import imageio.v3 as iio
    import imageio_ffmpeg

    try:
        iio.imwrite(path, np.stack(frames), extension=".mp4", fps=fps, codec="libx264", macro_block_size=1,
                    ffmpeg_log_level="quiet")  # its errors reach the user as one line, below
        written, _ = imageio_ffmpeg.count_frames_and_secs(str(path))
    except (OSError, RuntimeError) as exc:
        last = [line for line in str(exc).splitlines() if line.strip()][-1:] or ["no reason given"]
        raise OutputPathError(f"could not write the video {path} (ffmpeg: {last[0].strip()}); free some space or "
                              "choose another folder") from None
    if written != len(frames):
        raise OutputPathError(f"the video {path} holds {written} of its {len(frames)} frames (a full disk?); free "
                              "some space or choose another folder")
