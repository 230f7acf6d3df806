"""Videos written and then checked: ffmpeg reports a full disk in its own output, not by failing the
call, so a video counts as written only once its frames are read back."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from hoap_actions.errors import OutputPathError

__all__ = ["side_by_side", "write_video"]


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


def side_by_side(left: Sequence[np.ndarray], left_fps: float, right: Sequence[np.ndarray],
                 right_fps: float) -> list[np.ndarray]:
    """Two films played together at ``right_fps``: ``left`` (its own frame rate, scaled to the right's
    height) beside ``right``; the shorter one holds its last frame until the longer ends."""
    import cv2

    if not left or not right or left_fps <= 0 or right_fps <= 0:
        raise ValueError("side_by_side needs frames on both sides and positive frame rates")
    height = right[0].shape[0]
    width = 2 * round(left[0].shape[1] * height / left[0].shape[0] / 2)  # even: H.264's 4:2:0 pixels
    seconds = max(len(left) / left_fps, len(right) / right_fps)
    out = []
    for k in range(int(np.ceil(seconds * right_fps))):
        shown = left[min(int(k * left_fps / right_fps), len(left) - 1)]
        scaled = cv2.resize(np.ascontiguousarray(shown), (width, height), interpolation=cv2.INTER_AREA)
        out.append(np.concatenate([scaled, right[min(k, len(right) - 1)]], axis=1))
    return out
