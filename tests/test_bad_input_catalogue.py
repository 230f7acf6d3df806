"""The bad-input catalogue: what a user may pass that once killed the process or lost data.

One test per catalogue row, named after what it checks. Each row that could end the interpreter
runs in a subprocess, so a regression fails the test instead of ending pytest. The slow soak test
(tests/test_soak.py) runs rows 7-8 for 40 000 steps.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
import warnings

import gymnasium
import h5py
import numpy as np
import pytest

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.apps.cli import main
from hoap_actions.demonstration.datasets import load_demonstrations, write_demonstrations
from hoap_actions.errors import (
    DataExistsError,
    DataFileError,
    ExtrapolationWarning,
    InvalidInputError,
)
from hoap_actions.outputs import PARTIAL_MARK, claimed_file, claimed_files
from hoap_actions.primitives.discovery.estimator import PrimitiveDiscovery
from hoap_actions.primitives.hmm.parametric_hmm import EXTRAPOLATION_MARGIN, ParametricHMM
from hoap_actions.primitives.pipelines.discover import OUTPUT_FILES, discover_to_dir

PEG = "hoap_actions/PegInsert-v0"
SUBPROCESS_TIMEOUT = 120  # s


def run_python(code: str, env: dict[str, str] | None = None,
               timeout: float = SUBPROCESS_TIMEOUT) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter; whatever PyBullet does there cannot end this one."""
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, env=env, timeout=timeout
    )


def headless_env() -> dict[str, str]:
    env = dict(os.environ)
    env.pop("DISPLAY", None)
    return env


def cli(*args: str, timeout: float = SUBPROCESS_TIMEOUT) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "hoap_actions", *args], capture_output=True, text=True, timeout=timeout
    )


# --------------------------------------------------------------------------- rows 1-3: rendering
def test_row1_human_render_without_display_raises_instead_of_exiting():
    result = run_python(
        """
        import gymnasium, hoap_actions
        from hoap_actions.errors import DisplayUnavailableError
        try:
            gymnasium.make("hoap_actions/PegInsert-v0", render_mode="human")
        except DisplayUnavailableError as error:
            print("raised:", error)
        """,
        env=headless_env(),
    )
    assert result.returncode == 0, result.stderr
    assert "raised: render_mode='human' needs a display" in result.stdout
    assert "rgb_array" in result.stdout  # says what is accepted instead


def test_row1_human_render_with_unreachable_display_raises_instead_of_exiting():
    env = headless_env()
    env["DISPLAY"] = ":31999"  # no X server listens there
    result = run_python(
        """
        import gymnasium, hoap_actions
        from hoap_actions.errors import DisplayUnavailableError
        try:
            gymnasium.make("hoap_actions/Reach-v1", render_mode="human")
        except DisplayUnavailableError as error:
            print("raised:", error)
        """,
        env=env,
    )
    assert result.returncode == 0, result.stderr
    assert "cannot open the X display" in result.stdout


def test_row2_check_env_without_skip_render_check_reports_an_error_headless():
    result = run_python(
        """
        import gymnasium, hoap_actions
        from gymnasium.utils.env_checker import check_env
        from hoap_actions.errors import DisplayUnavailableError
        env = gymnasium.make("hoap_actions/Reach-v1")
        try:
            check_env(env.unwrapped)
        except DisplayUnavailableError as error:
            print("reported:", type(error).__name__)
        """,
        env=headless_env(),
    )
    assert result.returncode == 0, result.stderr
    assert "reported: DisplayUnavailableError" in result.stdout


@pytest.fixture(scope="module")
def x_display():
    """A display for PyBullet's GUI: a private Xvfb server. CI sets HOAP_ACTIONS_REQUIRE_DISPLAY=1 (and
    installs xvfb), so there a missing server fails the test instead of skipping it."""
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        if os.environ.get("HOAP_ACTIONS_REQUIRE_DISPLAY") == "1":
            pytest.fail("Xvfb is not installed, and HOAP_ACTIONS_REQUIRE_DISPLAY=1 asks for the GUI tests")
        pytest.skip("Xvfb is not installed (Debian: apt-get install xvfb)")
    read_end, write_end = os.pipe()
    server = subprocess.Popen([xvfb, "-displayfd", str(write_end), "-screen", "0", "1024x768x24", "-nolisten", "tcp"],
                              pass_fds=(write_end,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write_end)
    with os.fdopen(read_end) as reader:
        number = reader.readline().strip()  # Xvfb writes its display number once it accepts clients
    try:
        assert number, "Xvfb did not start"
        yield f":{number}"
    finally:
        server.terminate()
        server.wait(timeout=SUBPROCESS_TIMEOUT)


def test_human_mode_steps_and_renders_under_a_virtual_x_server(x_display):
    env = headless_env()
    env["DISPLAY"] = x_display
    result = run_python(
        """
        import gymnasium, hoap_actions, numpy as np
        from gymnasium.utils.env_checker import check_env
        from hoap_actions.errors import DisplayUnavailableError
        env = gymnasium.make("hoap_actions/Reach-v1", render_mode="human")
        env.reset(seed=0)
        for _ in range(30):
            env.step(env.action_space.sample())
        assert env.render() is None  # human mode draws in the window, as Gymnasium specifies
        image = env.unwrapped.sim.render("front").rgb  # the window's OpenGL renderer
        print("distinct colours", len(np.unique(image.reshape(-1, 3), axis=0)))
        try:
            gymnasium.make("hoap_actions/Reach-v1", render_mode="human")
        except DisplayUnavailableError as error:
            print("second window:", error)
        env.close()
        check_env(gymnasium.make("hoap_actions/Reach-v1").unwrapped)  # makes and renders the human env too
        print("check_env passed")
        """,
        env=env,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    colours = int(result.stdout.split("distinct colours")[1].split()[0])
    assert colours > 20  # a rendered scene, not a blank frame
    assert "second window: PyBullet could not open its GUI server" in result.stdout
    assert "check_env passed" in result.stdout


@pytest.mark.parametrize(
    "size", [{"render_width": -5}, {"render_height": -1}, {"render_width": 0}, {"render_width": 1.7},
             {"render_width": 100_000, "render_height": 100_000}, {"render_width": True}]
)
def test_row3_render_sizes_outside_whole_1_to_4096_pixels_are_refused(size):
    with pytest.raises(InvalidInputError, match=r"integer number of pixels in 1\.\.4096"):
        gymnasium.make(PEG, render_mode="rgb_array", **size)


def test_row3_accepted_render_size_gives_that_image():
    env = gymnasium.make("hoap_actions/Reach-v1", render_mode="rgb_array", render_width=64, render_height=48)
    env.reset(seed=0)
    assert env.render().shape == (48, 64, 3)
    env.close()


# ------------------------------------------------------------------- rows 4-6: outputs and claims
def _race_writer(path: str, tag: float, barrier, results) -> None:
    """Worker: write a dataset tagged ``tag`` to ``path`` the moment every worker is ready."""
    demos = _tagged_demos(tag)
    barrier.wait()
    try:
        write_demonstrations(path, demos)
        results.put(("won", tag))
    except DataExistsError as error:
        results.put(("refused", str(error)))


def _tagged_demos(tag: float):
    """A valid one-episode dataset whose hand markers all equal ``tag`` (to tell the writers apart)."""
    from hoap_actions.demonstration.datasets import N_MARKERS, Demonstrations, Episode, GroundTruth

    T = 20
    truth = GroundTruth(
        labels=np.zeros(T, dtype=np.int64), phase_names=("approach",), action="approach", direction="",
        distance=0.0, angle=0.0, object_start=np.zeros(6), object_end=np.zeros(6), object_target=np.zeros(6),
        hand_rest=np.zeros(3), repetition=0, grid="", grid_index=np.zeros(2, dtype=np.int64),
    )
    episode = Episode(H=np.full((T, N_MARKERS, 3), tag), O=np.zeros((T, 6)), ground_truth=truth, seed=(0, 1))
    names = tuple(f"m{i}" for i in range(N_MARKERS))
    return Demonstrations(episodes=(episode,), fps=30.0, marker_names=names, phase_names=("approach",), seed=0,
                          scene={}, generator={})


def test_row4_concurrent_dataset_writers_one_wins_the_others_get_exists(tmp_path):
    path = str(tmp_path / "demos.h5")
    context = multiprocessing.get_context("fork")
    n = 4
    barrier, results = context.Barrier(n), context.Queue()
    workers = [context.Process(target=_race_writer, args=(path, float(k + 1), barrier, results)) for k in range(n)]
    for w in workers:
        w.start()
    outcomes = [results.get(timeout=SUBPROCESS_TIMEOUT) for _ in workers]
    for w in workers:
        w.join(timeout=SUBPROCESS_TIMEOUT)
    winners = [tag for kind, tag in outcomes if kind == "won"]
    refusals = [text for kind, text in outcomes if kind == "refused"]
    assert len(winners) == 1 and len(refusals) == n - 1
    assert all("already exists" in text or "another process is writing" in text for text in refusals)
    assert np.all(load_demonstrations(path)[0].H == winners[0])  # the file is the winner's, whole
    assert not list(tmp_path.glob(f"*{PARTIAL_MARK}*"))


def test_row4_dataset_writer_refuses_while_another_holds_the_claim(tmp_path):
    path = tmp_path / "demos.h5"
    with claimed_file(path, what="dataset") as partial:
        with pytest.raises(DataExistsError, match="another process is writing"):
            write_demonstrations(path, _tagged_demos(1.0))
        partial.write_text("the first claimant's")
    assert path.read_text() == "the first claimant's"


def test_row5_discover_refuses_an_output_folder_another_run_is_writing(tmp_path, capsys):
    out = tmp_path / "primitives"
    demos = write_demonstrations(tmp_path / "demos.h5", _tagged_demos(1.0))
    with pytest.raises(KeyboardInterrupt):  # the first run is interrupted after the second one tried
        with claimed_files(out, OUTPUT_FILES, what="discovery results"):
            assert main(["discover", "--demos", str(demos), "--out", str(out)]) == 2
            raise KeyboardInterrupt
    assert "another process is writing" in capsys.readouterr().err
    assert not out.exists()  # neither run left anything: the folder they created is gone too


def test_row5_claimed_files_publish_all_or_none(tmp_path):
    out = tmp_path / "results"
    out.mkdir()
    (out / "b.txt").write_text("someone else's")
    with pytest.raises(DataExistsError, match="b.txt"):
        with claimed_files(out, ["a.txt", "b.txt"]):
            pass
    with pytest.raises(RuntimeError):
        with claimed_files(out, ["a.txt", "c.txt"]) as staging:
            (staging / "a.txt").write_text("new")
            raise RuntimeError("the job failed")
    with pytest.raises(FileNotFoundError):  # c.txt never written: a.txt must not be published alone
        with claimed_files(out, ["a.txt", "c.txt"]) as staging:
            (staging / "a.txt").write_text("new")
    assert sorted(p.name for p in out.iterdir()) == ["b.txt"]


@pytest.fixture
def no_long_work(monkeypatch):
    """Fail the test if a command gets as far as its long work."""

    def forbidden(*args, **kwargs):
        raise AssertionError("long work started before the arguments and outputs were checked")

    import hoap_actions.apps.episode_commands as cli_module
    import hoap_actions.demonstration.recording as recording
    import hoap_actions.primitives.pipelines.discover as discovery_files

    monkeypatch.setattr(recording, "_record_tasks", forbidden)
    monkeypatch.setattr(cli_module, "compare_policies", forbidden)
    monkeypatch.setattr(cli_module, "film_episode", forbidden)
    monkeypatch.setattr(discovery_files, "_discover", forbidden)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["record", "--preset", "small", "--out", "/proc/x.h5"], "cannot write the dataset in /proc"),
        (["record", "--preset", "small", "--out", "{tmp}", "--overwrite"], "is a directory"),
        (["record", "--preset", "small", "--out", "{tmp}/existing.h5"], "already exists"),
        (["demo", "--video", "/proc/x.mp4"], "cannot write the video in /proc"),
        (["demo", "--json", "/proc/x.json"], "cannot write the report in /proc"),
        (["demo", "--snapshot", "{tmp}/existing.h5"], "already exists"),
        (["discover", "--demos", "{tmp}/existing.h5", "--out", "/proc/x"], "cannot create the folder /proc/x"),
    ],
)
def test_row6_outputs_are_checked_before_long_work_starts(argv, message, tmp_path, no_long_work, capsys):
    (tmp_path / "existing.h5").write_bytes(b"a user's file")
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1  # one line
    assert (tmp_path / "existing.h5").read_bytes() == b"a user's file"


def test_row6_seed_beyond_int64_is_refused_before_recording(tmp_path, no_long_work, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["record", "--preset", "small", "--out", str(tmp_path / "a.h5"), "--seed", "9223372036854775808"])
    assert exit_info.value.code == 2
    assert "a seed is an integer in 0..9223372036854775807" in capsys.readouterr().err


# ------------------------------------------------------------------------ rows 12-15: arguments
@pytest.mark.parametrize("episodes", ["0", "-1"])
def test_row12_demo_refuses_fewer_than_one_episode(episodes, no_long_work, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["demo", "--episodes", episodes])
    assert exit_info.value.code == 2
    assert "must be a positive integer" in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv, message",
    [
        (["record", "--preset", "small", "--out", "x.h5", "--seed", "-1"], "a seed is an integer in 0.."),
        (["demo", "--seed", "-1"], "a seed is an integer in 0.."),
        (["demo", "--seed", "9223372036854775807", "--episodes", "2"], "seeds "
                                                                       "9223372036854775807..9223372036854775808 "
                                                                       "outside"),
        (["demo", "--env", "bogus/Env-v0"], "invalid choice: 'bogus/Env-v0' (choose from 'hoap_actions/PegInsert-v0'"),
        (["demo", "--env", "CartPole-v1"], "invalid choice: 'CartPole-v1'"),
    ],
)
def test_row13_bad_seeds_and_env_ids_exit_2_with_one_line(argv, message):
    result = cli(*argv)
    assert result.returncode == 2
    assert message in result.stderr
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr


def test_row13_scripted_policy_outside_its_envs_is_refused(no_long_work, capsys):
    assert main(["demo", "--policy", "scripted", "--env", "hoap_actions/Reach-v1"]) == 2
    assert "acts in ['hoap_actions/PegInsert-v0']" in capsys.readouterr().err


@pytest.fixture(scope="module")
def peg_env():
    env = gymnasium.make(PEG)
    env.reset(seed=0)
    yield env
    env.close()


@pytest.mark.parametrize("action", ["abc", {"a": 1}, [[1, 2], [3]], None])
def test_row14_non_numeric_actions_raise_the_projects_error_with_the_accepted_shape(peg_env, action):
    with pytest.raises(InvalidInputError, match=r"expects an array of 7 finite numbers in \[-1, 1\]"):
        peg_env.step(action)


def test_row15_out_of_range_actions_are_clipped_and_info_says_so():
    runs = []
    for action in (np.full(7, 5.0), np.ones(7)):
        env = gymnasium.make(PEG)
        env.reset(seed=3)
        obs, _, _, _, info = env.step(action)
        runs.append((obs["observation"], info["action_clipped"]))
        env.close()
    (clipped_obs, clipped_flag), (unit_obs, unit_flag) = runs
    assert clipped_flag and not unit_flag
    np.testing.assert_array_equal(clipped_obs, unit_obs)  # 5.0 acts exactly as 1.0


# ------------------------------------------------------------ rows 7-8: balance and servo speeds
def test_row7_ee_delta_random_actions_seed_1001_do_not_fall():
    """These 800 actions (float32, as the action space's samples) on the layout of seed
    1001 made the robot fall at step 529. The knees cycled at the IK's speed limit and the body's
    motion rocked the feet until they tipped over the heels."""
    env = gymnasium.make("hoap_actions/PegInsert-v0", control_mode="ee_delta").unwrapped
    env.reset(seed=1001)
    actions = np.random.default_rng(123).uniform(-1, 1, (2000, 4))[1200:].astype(np.float32)
    for step, action in enumerate(actions, start=1):
        _, _, terminated, _, info = env.step(action)
        assert not info["fallen"], f"the robot fell at step {step}"
        assert not terminated, f"the episode ended at step {step} without a fall: {info}"
    env.close()


def test_row8_joint_delta_joint_speeds_stay_within_their_limits():
    """Random joint_delta actions, watched every physics tick: the motors' maxVelocity alone let
    contacts and the other joints whip a 5 rad/s joint to 23 rad/s; the solver's clamp holds them."""
    env = gymnasium.make("hoap_actions/PegInsert-v0")
    base = env.unwrapped
    robot, sim = base.robot, base.sim
    fastest = np.zeros(len(robot.joint_names))
    step_physics = sim.step

    def step_and_watch(n: int = 1) -> None:
        for _ in range(n):
            step_physics(1)
            np.maximum(fastest, np.abs(robot.joint_velocities()), out=fastest)

    sim.step = step_and_watch
    env.reset(seed=3)
    rng = np.random.default_rng(3)
    for _ in range(400):
        _, _, terminated, truncated, _ = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
        if terminated or truncated:
            env.reset()
    env.close()
    ratio = fastest / robot.max_velocity
    worst = int(np.argmax(ratio))
    assert ratio[worst] <= 1.0 + 1e-6, f"{robot.joint_names[worst]} reached {fastest[worst]:.2f} rad/s"
    assert ratio.max() > 0.5, "the random actions hardly moved the joints"


# ---------------------------------------------------------------------- rows 9-11: model files
K, D = 3, 2
PHI_LOW, PHI_HIGH = 0.0, 1.0  # the training effects' range


@pytest.fixture(scope="module")
def saved_model(tmp_path_factory):
    """A left-right PHMM trained on sequences whose state means move linearly with a scalar effect, saved."""
    rng = np.random.default_rng(0)
    mean_bar = np.cumsum(rng.normal(size=(K, D)), axis=0)
    w = rng.normal(size=(K, D, 1))
    phis = np.linspace(PHI_LOW, PHI_HIGH, 8)[:, None]
    seqs = []
    for phi in phis:
        states = np.repeat(np.arange(K), rng.integers(3, 6, size=K))
        seqs.append((mean_bar + w @ phi)[states] + 0.05 * rng.normal(size=(states.size, D)))
    model = ParametricHMM(n_states=K, random_state=0).fit(np.concatenate(seqs), [len(s) for s in seqs], phis)
    path = tmp_path_factory.mktemp("models") / "model.npz"
    model.save(path)
    return path


# Row 9: a saved model edited into meaningless values loaded, then synthesize ran out of memory
# ("Maximum allowed size exceeded") and score returned -inf silently.
@pytest.mark.parametrize(
    "edit, entry",
    [
        (lambda a: {"transmat_": np.full((K, K), 5.0)}, "transmat_"),
        (lambda a: {"transmat_": -a["transmat_"]}, "transmat_"),
        (lambda a: {"startprob_": np.zeros(K)}, "startprob_"),
        (lambda a: {"covars_": -a["covars_"]}, "covars_"),
        (lambda a: {"transmat_": a["transmat_"].T / a["transmat_"].T.sum(axis=1, keepdims=True)}, "transmat_"),
    ],
    ids=["transmat-all-5", "transmat-negated", "startprob-zero", "covars-not-positive-definite",
         "chain-runs-backwards"],
)
def test_row9_load_rejects_saved_values_that_are_not_a_valid_hmm(saved_model, tmp_path, edit, entry):
    with np.load(saved_model, allow_pickle=False) as raw:
        arrays = dict(raw)
    bad = tmp_path / "edited.npz"
    np.savez(bad, **{**arrays, **edit(arrays)})
    with pytest.raises(DataFileError, match=f"edited.npz: entry {entry}.*accepted"):
        ParametricHMM.load(bad)


# Row 10: loading a JSON or HDF5 file suggested loading it with allow_pickle (unsafe, and wrong).
def test_row10_load_says_a_json_or_hdf5_file_is_not_a_model_and_never_suggests_allow_pickle(tmp_path):
    json_file = tmp_path / "model.json"
    json_file.write_text(json.dumps({"kind": "PrimitiveDiscovery", "format_version": 1}))
    hdf5_file = tmp_path / "demos.h5"
    with h5py.File(hdf5_file, "w") as f:
        f["H"] = np.zeros((3, 6, 3))
    for path, looks_like in ((json_file, "JSON"), (hdf5_file, "HDF5")):
        with pytest.raises(DataFileError) as caught:
            ParametricHMM.load(path)
        message = str(caught.value)
        assert "not a ParametricHMM file" in message and looks_like in message and ".npz" in message
        assert "pickle" not in message


# Row 11: synthesize(phi) with phi 100x the training range extrapolated without a word.
def test_row11_synthesize_warns_far_outside_the_training_effects_and_names_their_range(saved_model):
    model = ParametricHMM.load(saved_model)
    span = PHI_HIGH - PHI_LOW
    with pytest.warns(ExtrapolationWarning, match=r"phi\[0\] = 100, trained on \[0, 1\]"):
        model.synthesize([100.0 * PHI_HIGH])
    with pytest.warns(ExtrapolationWarning):
        model.synthesize([PHI_LOW - 1.01 * EXTRAPOLATION_MARGIN * span])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # inside the widened range: no warning
        model.synthesize([PHI_HIGH + 0.99 * EXTRAPOLATION_MARGIN * span])
        model.synthesize([0.5 * (PHI_LOW + PHI_HIGH)])


# ------------------------------------------------------------------- rows 16-18: dataset files
@pytest.fixture(scope="module")
def small(small_recording):
    """A recorded ``small`` preset dataset (4 episodes: approach, push, move, rotate)."""
    return small_recording


def edited_dataset(small, tmp_path, edit):
    """A copy of the small dataset with ``edit(file)`` applied to it."""
    path = tmp_path / "edited.h5"
    shutil.copyfile(small, path)
    with h5py.File(path, "r+") as f:
        edit(f)
    return path


def replace(f, name, data):
    del f[name]
    f[name] = data


# Row 16: a dataset with episode_00001/H deleted: the error named the file but not the episode.
def test_row16_missing_array_error_names_the_episode_and_the_entry(small, tmp_path):
    path = edited_dataset(small, tmp_path, lambda f: f.__delitem__("episode_00001/H"))
    with pytest.raises(DataFileError, match="edited.h5:episode_00001: entry H is missing; every episode holds H, O"):
        load_demonstrations(path)


# Row 17: a dataset whose ground_truth/object_start has shape (2,) was accepted and discover ran.
def test_row17_ground_truth_entries_of_the_wrong_shape_are_rejected_on_load(small, tmp_path):
    wrong = {"object_start": np.zeros(2), "object_end": np.zeros(7), "object_target": np.zeros((6, 1)),
             "hand_rest": np.zeros(2), "grid_index": np.zeros(3, dtype=np.int64)}
    for name, value in wrong.items():
        path = edited_dataset(small, tmp_path,
                              lambda f, name=name, value=value: replace(f, f"episode_00001/ground_truth/{name}", value))
        with pytest.raises(DataFileError, match=f"episode_00001: entry ground_truth/{name} has shape"):
            load_demonstrations(path)
    with pytest.raises(DataFileError, match="episode_00001: entry ground_truth/object_start"):
        discover_to_dir(edited_dataset(small, tmp_path, lambda f: replace(
            f, "episode_00001/ground_truth/object_start", np.zeros(2))), tmp_path / "out")


# Row 18: discover on a dataset whose object poses O have 1e300 added: a scipy traceback.
def test_row18_implausible_object_poses_are_named_by_episode_and_frame(small, tmp_path):
    def far_away(f):
        replace(f, "episode_00001/O", f["episode_00001/O"][()] + 1e300)

    with pytest.raises(DataFileError, match=r"edited.h5:episode_00001: O frame 0 has an object coordinate of 1e\+300"):
        discover_to_dir(edited_dataset(small, tmp_path, far_away), tmp_path / "out")
    demos = load_demonstrations(small)
    X, lengths = np.concatenate([episode.O for episode in demos]), [episode.T for episode in demos]
    row = sum(lengths[:2]) + 9
    X[row, 3:] += 1e300  # the rotation vector alone: scipy's "zero norm quaternions" before
    with pytest.raises(InvalidInputError, match=rf"X demonstration 2 frame 9 \(row {row}\) has a rotation vector"):
        PrimitiveDiscovery().fit(X, lengths)


# ---------------------------------------------------------------------- rows 19-21: the command line
def test_row19_empty_output_path_is_refused(no_long_work, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["record", "--preset", "small", "--out", ""])
    assert exit_info.value.code == 2
    assert "an empty path" in capsys.readouterr().err


def _wait_for(predicate, timeout: float = 60.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return False


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_row20_an_interrupted_record_leaves_no_partial_file(tmp_path, sig):
    """The child gets SIGINT's default action even when the tests run in a background job (which
    ignores SIGINT, and a child inherits that)."""
    out = tmp_path / "demos.h5"
    process = subprocess.Popen([sys.executable, "-m", "hoap_actions", "record", "--preset", "paper", "--out", str(out)],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert _wait_for(lambda: list(tmp_path.glob(f".*{PARTIAL_MARK}*"))), "the run never claimed its output"
    process.send_signal(sig)
    _, err = process.communicate(timeout=SUBPROCESS_TIMEOUT)
    assert process.returncode == 130 and "interrupted" in err
    assert list(tmp_path.iterdir()) == []


def test_row20_a_killed_records_partial_is_swept_by_the_next_run(tmp_path):
    out = tmp_path / "demos.h5"
    process = subprocess.Popen([sys.executable, "-m", "hoap_actions", "record", "--preset", "paper", "--out", str(out)],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    assert _wait_for(lambda: list(tmp_path.glob(f".*{PARTIAL_MARK}*")))
    process.kill()  # SIGKILL: nothing runs in the process, its partial stays
    process.wait(timeout=SUBPROCESS_TIMEOUT)
    assert list(tmp_path.glob(f".*{PARTIAL_MARK}*"))
    with claimed_file(tmp_path / "other.txt") as partial:  # any later claim in the folder
        partial.write_text("x")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.txt"]


def test_row21_cli_output_is_only_what_the_command_says():
    result = cli("demo", "--env", "hoap_actions/Reach-v1", "--episodes", "1")
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("random policy on hoap_actions/Reach-v1 (full robot): success rate")
    assert "argv" not in result.stdout
    assert result.stderr == ""  # no PyBullet build line, no placo/hppfcl DeprecationWarning
