"""hoap-actions imitate: replaying a recording's episodes, its checks before any episode runs, and the video
that plays the demonstration (with the arm the robot took from it) beside the robot."""

from __future__ import annotations

import json

import imageio.v3 as iio
import numpy as np
import pytest

from hoap_actions.apps.cli import main
from hoap_actions.apps.videos import side_by_side
from hoap_actions.envs.camera import Camera
from hoap_actions.errors import InvalidInputError
from hoap_actions.imitation.demonstrations import Demonstration
from hoap_actions.imitation.film import annotated_frames

APPROACH = 3  # the small recording's episodes: push, move, rotate, approach


def test_a_replayed_episode_is_imitated_and_filmed_beside_its_demonstration(small_recording, tmp_path, capsys):
    video, report = tmp_path / "i.mp4", tmp_path / "i.json"
    assert main(["imitate", "--from-markers", "--demos", str(small_recording), "--episode", str(APPROACH),
                 "--seed", "5", "--video", str(video), "--json", str(report)]) == 0
    out = capsys.readouterr().out
    assert f"demonstrations from {small_recording}" in out and "over 1 episodes" in out
    assert "per episode: reading the demonstration" in out
    document = json.loads(report.read_text())
    assert document["reset_options"] == [{"demonstration": [str(small_recording), APPROACH]}]
    episode = document["policies"]["imitation-markers"]["episodes"][0]
    assert (episode["seed"], episode["recognised"]) == (5, "approach")
    frames = iio.imread(video)
    # the demonstration's camera (4:3) scaled to the robot's height, then the robot's 320 x 240 view
    assert frames.shape[1:] == (240, 320 + 320, 3)


@pytest.mark.parametrize("argv, message", [
    (["--episode", "9"], "--episode 9 is not in the recording"),
    (["--demonstrator", "tall"], "a recording (--demos) already has its own"),
    (["--episodes", "2"], "pick the recording's episodes with --episode"),
])
def test_bad_replays_are_one_line_before_any_episode(small_recording, capsys, argv, message):
    assert main(["imitate", "--demos", str(small_recording), *argv]) == 2
    assert message in capsys.readouterr().err


def test_an_episode_without_a_recording_is_refused(capsys):
    assert main(["imitate", "--episode", "0"]) == 2
    assert "give the recording with --demos" in capsys.readouterr().err


def test_side_by_side_plays_both_films_in_real_time_and_holds_the_shorter():
    left = [np.full((60, 80, 3), k, np.uint8) for k in range(10)]  # 1 s at 10 Hz
    right = [np.full((30, 20, 3), 100 + k, np.uint8) for k in range(45)]  # 1.5 s at 30 Hz
    out = side_by_side(left, 10.0, right, 30.0)
    assert len(out) == 45 and out[0].shape == (30, 40 + 20, 3)
    assert [int(frame[0, 0, 0]) for frame in out[:31:3]] == [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9]
    assert int(out[44][0, -1, 0]) == 144
    with pytest.raises(ValueError):
        side_by_side([], 10.0, right, 30.0)


def test_the_arm_is_drawn_where_the_camera_sees_its_markers():
    camera = Camera(eye=(1.0, 0.0, 1.0), target=(0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0), fov_deg=60.0, width=160,
                    height=120)
    frames = np.zeros((2, 120, 160, 3), np.uint8)
    shown = Demonstration(frames, camera, 30.0, frames[0])
    names = ("shoulder", "elbow", "wrist", "index_tip", "index_knuckle", "thumb_tip")
    markers = np.zeros((2, 6, 3))
    markers[:, :, 1] = np.linspace(-0.2, 0.2, 6)
    markers[1] = np.nan  # a frame without an estimate is left bare
    drawn = annotated_frames(shown, markers, names, [])
    u, v = np.round(camera.pixels(markers[0, 1])[0]).astype(int)
    assert drawn[0][v, u].any() and not drawn[1].any()
    with pytest.raises(InvalidInputError, match=r"\(T, M, 3\)"):
        annotated_frames(shown, markers[:1], names, [])


def test_reset_options_come_one_per_seed():
    from hoap_actions.apps.episodes import compare_policies

    with pytest.raises(InvalidInputError, match="one entry per seed"):
        compare_policies("hoap_actions/Imitate-v0", {"nothing": ("nothing", {})}, [1, 2], options=[None])


def test_paired_outcomes_count_the_discordant_episodes_and_give_mcnemars_exact_p():
    from hoap_actions.apps.episodes import paired_outcomes

    def run(successes):
        return [{"seed": k, "success": bool(s)} for k, s in enumerate(successes)]

    first, second = run([1] * 5 + [1, 0, 0]), run([0] * 5 + [1, 0, 0])
    out = paired_outcomes(first, second)
    assert (out["only_first"], out["only_second"]) == (5, 0)
    assert out["mcnemar_p"] == pytest.approx(2 * 0.5 ** 5)  # two-sided exact binomial of 0 in 5
    assert out["difference"] == pytest.approx(5 / 8)
    assert out["difference_ci95"][0] <= 5 / 8 <= out["difference_ci95"][1]
    assert paired_outcomes(first, first)["mcnemar_p"] == 1.0
    with pytest.raises(InvalidInputError, match="same seeds"):
        paired_outcomes(first, run([1, 0]))
