"""Gymnasium's RecordVideo on the package's envs, with the ``video`` extra installed."""

from __future__ import annotations

import gymnasium
import imageio.v3 as iio
import pytest

import hoap_actions  # noqa: F401  (registers the environments)

pytest.importorskip("moviepy")


def test_record_video_writes_the_close_up_of_an_episode(tmp_path):
    from gymnasium.wrappers import RecordVideo

    env = RecordVideo(gymnasium.make("hoap_actions/Reach-v1", render_mode="rgb_array", camera="closeup"),
                      str(tmp_path), episode_trigger=lambda episode: episode == 0, disable_logger=True)
    env.reset(seed=0)
    env.action_space.seed(0)
    for _ in range(15):
        env.step(env.action_space.sample())
    env.close()
    videos = sorted(tmp_path.glob("*.mp4"))
    assert [v.name for v in videos] == ["rl-video-episode-0.mp4"]
    frames = iio.imread(videos[0])
    assert frames.shape[1:] == (240, 320, 3) and len(frames) >= 15
