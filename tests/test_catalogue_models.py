"""Reliability catalogue, model and dataset rows: edited or foreign files and far-out inputs must give a
clear error (or warning) naming what is wrong, never load silently, crash later or suggest unsafe loading."""

from __future__ import annotations

import json
import warnings

import h5py
import numpy as np
import pytest

from hoap_actions.errors import DataFileError, ExtrapolationWarning
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
