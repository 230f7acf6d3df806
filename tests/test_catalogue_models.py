"""Reliability catalogue, model and dataset rows: edited or foreign files and far-out inputs must give a
clear error (or warning) naming what is wrong, never load silently, crash later or suggest unsafe loading."""

from __future__ import annotations

import json
import shutil
import warnings

import h5py
import numpy as np
import pytest

from hoap_actions.errors import DataFileError, ExtrapolationWarning, InvalidInputError
from hoap_actions.primitives.datasets import load_demonstrations
from hoap_actions.primitives.discovery import PrimitiveDiscovery
from hoap_actions.primitives.discovery_report import discover_to_dir
from hoap_actions.primitives.parametric_hmm import EXTRAPOLATION_MARGIN, ParametricHMM

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
def test_load_rejects_saved_values_that_are_not_a_valid_hmm(saved_model, tmp_path, edit, entry):
    with np.load(saved_model, allow_pickle=False) as raw:
        arrays = dict(raw)
    bad = tmp_path / "edited.npz"
    np.savez(bad, **{**arrays, **edit(arrays)})
    with pytest.raises(DataFileError, match=f"edited.npz: entry {entry}.*accepted"):
        ParametricHMM.load(bad)


# Row 10: loading a JSON or HDF5 file suggested loading it with allow_pickle (unsafe, and wrong).
def test_load_says_a_json_or_hdf5_file_is_not_a_model_and_never_suggests_allow_pickle(tmp_path):
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
def test_synthesize_warns_far_outside_the_training_effects_and_names_their_range(saved_model):
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


# ------------------------------------------------------------------------------------------ datasets
@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """A recorded ``small`` preset dataset (4 episodes: approach, push, move, rotate)."""
    from hoap_actions.envs.recording import record

    return record("small", tmp_path_factory.mktemp("demos") / "small.h5", seed=0, progress=False)


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
def test_missing_array_error_names_the_episode_and_the_entry(small, tmp_path):
    path = edited_dataset(small, tmp_path, lambda f: f.__delitem__("episode_00001/H"))
    with pytest.raises(DataFileError, match="edited.h5:episode_00001: entry H is missing; every episode holds H, O"):
        load_demonstrations(path)


# Row 17: a dataset whose ground_truth/object_start has shape (2,) was accepted and discover ran.
def test_ground_truth_entries_of_the_wrong_shape_are_rejected_on_load(small, tmp_path):
    wrong = {"object_start": np.zeros(2), "object_end": np.zeros(7), "object_target": np.zeros((6, 1)),
             "hand_rest": np.zeros(2), "grid_index": np.zeros(3, dtype=np.int64)}
    for name, value in wrong.items():
        path = edited_dataset(small, tmp_path, lambda f: replace(f, f"episode_00001/ground_truth/{name}", value))
        with pytest.raises(DataFileError, match=f"episode_00001: entry ground_truth/{name} has shape"):
            load_demonstrations(path)
    with pytest.raises(DataFileError, match="episode_00001: entry ground_truth/object_start"):
        discover_to_dir(edited_dataset(small, tmp_path, lambda f: replace(
            f, "episode_00001/ground_truth/object_start", np.zeros(2))), tmp_path / "out")


# Row 18: discover on a dataset whose object poses O have 1e300 added: a scipy traceback.
def test_implausible_object_poses_are_named_by_episode_and_frame(small, tmp_path):
    def far_away(f):
        replace(f, "episode_00001/O", f["episode_00001/O"][()] + 1e300)

    with pytest.raises(DataFileError, match=r"edited.h5:episode_00001: O frame 0 has an object coordinate of 1e\+300"):
        discover_to_dir(edited_dataset(small, tmp_path, far_away), tmp_path / "out")
    objects = [episode.O for episode in load_demonstrations(small)]
    objects[2] = objects[2].copy()
    objects[2][9, 3:] += 1e300  # the rotation vector alone: scipy's "zero norm quaternions" before
    with pytest.raises(InvalidInputError, match=r"trajectories\[2\] frame 9 has a rotation vector of angle"):
        PrimitiveDiscovery().fit(objects)
