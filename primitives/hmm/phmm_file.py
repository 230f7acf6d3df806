"""The file format of :meth:`ParametricHMM.save <hoap_actions.primitives.hmm.parametric_hmm.ParametricHMM.save>`
(``format_version`` 4; version 1 files, written before the covariance prior existed, load as models
without one; version 1 and 2 files, written before the mean model could bend, load as linear models;
files before version 4 hold ``train_phi_`` under the key ``train_params_``), an
uncompressed ``.npz`` archive readable with ``numpy.load(path, allow_pickle=False)``; every entry is a
plain numeric or unicode array:

=======================  ===================  ===============================================================
key                      shape                meaning
=======================  ===================  ===============================================================
format_version           () int               4
kind                     () str               "ParametricHMM"
n_states, n_iter         () int               hyper-parameters as given to ``__init__``
topology                 () str               "left-right", "left-right-skip" or "ergodic"
covariance_type          () str               "full" or "diag"
tol, reg_covar           () float             hyper-parameters
covars_prior             (0,) or (D,)         prior variances (empty: no prior)
covars_weight            () float             the prior's weight in frames per state
mean_model               () str               "linear" or "tps" (version 3)
smoothing                () float             ridge on V (version 3)
max_centres              () int               most thin-plate centres (version 3)
random_state             (0,) or (1,) int     the seed; empty when it was not an int (None or a Generator)
startprob_               (K,)                 initial state distribution
transmat_                (K, K)               transition matrix (rows sum to 1)
mean_bar_                (K, D)               state means at phi = 0
W_                       (K, D, p)            effect-to-mean matrices
V_                       (K, D, m)            feature-to-mean matrices (m = 0: linear; version 3)
feature_centres_         (m, p)               thin-plate centres in the unit box of the training range (v3)
feature_low_, _span_     (p,)                 that box: q = (phi - low) / span (version 3)
covars_                  (K, D, D) or (K, D)  covariances ("full") or variances ("diag")
train_phi_               (S, p), S >= 1       effects phi of the training sequences (restarts of estimate_phi;
                                              synthesize warns far outside their range)
log_likelihood_history_  (I,)                 training log-likelihood per EM iteration
converged_               () bool              whether training stopped on ``tol``
=======================  ===================  ===============================================================

:meth:`ParametricHMM.load` checks meaning as well as shapes: ``startprob_`` and every row of
``transmat_`` are probability distributions, a left-right chain starts in state 0 and only stays or
moves right (by one state, or two with skips), and covariances are symmetric positive definite.
"""

from __future__ import annotations

import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from hoap_actions.errors import DataFileError, InvalidInputError
from hoap_actions.inputs import checked_input_file
from hoap_actions.outputs import claimed_file
from hoap_actions.primitives.hmm.effect_features import ThinPlateFeatures
from hoap_actions.primitives.hmm.hmm_math import precision_cholesky

__all__ = ["FORMAT_VERSION", "READABLE_VERSIONS", "check_learned_meaning", "model_from_arrays", "read_model",
           "write_model"]

FORMAT_VERSION = 4
READABLE_VERSIONS = (1, 2, 3, 4)
# Loading: how a file is recognised, and how far saved values may be from what EM produces.
_ZIP_SIGNATURES = (b"PK\x03\x04", b"PK\x05\x06")  # an .npz archive is a zip file (with members / empty)
_OTHER_SIGNATURES = (
    (b"\x89HDF\r\n\x1a\n", "an HDF5 file (such as a demonstrations dataset)"),
    (b"\x93NUMPY", "a single .npy array, not an .npz archive"),
)
_SNIFF_BYTES = 16
MAX_NPZ_BYTES = 2**30  # the largest archive read: a 40-state full-covariance PHMM is a few MB
MAX_ARRAY_BYTES = 2**30  # what its entries may declare in all
_HEADER_READERS = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}
_ACCEPTED_FILES = "ParametricHMM.load reads the .npz archives written by ParametricHMM.save"
# Entries stored under another name than their attribute (the file format is older than the name phi).
_TRAIN_PHI_ENTRY = {1: "train_params_", 2: "train_params_", 3: "train_params_", 4: "train_phi_"}
_PROBABILITY_TOLERANCE = 1e-6  # |sum - 1| of a saved distribution; EM's normalisation errs by ~1e-16
_SYMMETRY_TOLERANCE = 1e-8  # largest |S - S^T| relative to the largest |S| (EM's covariances are exactly symmetric)


def write_model(model: Any, path: Path, overwrite: bool) -> None:
    """Write ``model``'s versioned ``.npz`` archive documented in this module."""
    seed = model.random_state
    arrays = {
        "format_version": np.array(model._format_version),
        "kind": np.array(model._file_kind),
        "n_states": np.array(int(model.n_states)),
        "topology": np.array(str(model.topology)),
        "covariance_type": np.array(str(model.covariance_type)),
        "n_iter": np.array(int(model.n_iter)),
        "tol": np.array(float(model.tol)),
        "reg_covar": np.array(float(model.reg_covar)),
        "random_state": np.array([int(seed)] if isinstance(seed, (int, np.integer)) else [], dtype=np.int64),
        "covars_prior": np.zeros(0) if model.covars_prior is None else np.asarray(model.covars_prior, dtype=float),
        "covars_weight": np.array(float(model.covars_weight)),
        "mean_model": np.array(str(model.mean_model)),
        "smoothing": np.array(float(model.smoothing)),
        "max_centres": np.array(int(model.max_centres)),
        "startprob_": model.startprob_,
        "transmat_": model.transmat_,
        "mean_bar_": model.mean_bar_,
        "W_": model.W_,
        "V_": model.V_,
        "feature_centres_": model.effect_features_.centres,
        "feature_low_": model.effect_features_.low,
        "feature_span_": model.effect_features_.span,
        "covars_": model.covars_,
        "train_phi_": model.train_phi_,
        "log_likelihood_history_": getattr(model, "log_likelihood_history_", np.zeros(0)),
        "converged_": np.array(bool(getattr(getattr(model, "monitor_", None), "converged", False))),
    }
    with claimed_file(path, overwrite, what="ParametricHMM file") as partial:
        with open(partial, "wb") as fh:
            np.savez(fh, **arrays)

def read_model(path: Path) -> tuple[Any, Any, dict[str, np.ndarray]]:
    """The archive's ``kind``, ``format_version`` (as Python values; None if absent) and entries."""
    if not path.is_file():
        raise DataFileError(f"model file {path} does not exist")
    arrays = _read_npz(path)
    kind, version = arrays.get("kind"), arrays.get("format_version")
    return (None if kind is None else kind.tolist()), (None if version is None else version.tolist()), arrays

def model_from_arrays(cls: type, path: Path, arrays: dict[str, np.ndarray], version: int) -> Any:
    """The model in the entries of a readable archive, checked for meaning as well as shape.

    An archive whose learned values a trained model cannot have (probabilities that do not sum to
    1, covariances that are not positive definite, ...) raises DataFileError: it would load and
    then fail far away.
    """
    try:
        seed = arrays["random_state"]
        model = cls(n_states=int(arrays["n_states"]), topology=str(arrays["topology"]),
                    covariance_type=str(arrays["covariance_type"]), n_iter=int(arrays["n_iter"]),
                    tol=float(arrays["tol"]), reg_covar=float(arrays["reg_covar"]),
                    random_state=int(seed[0]) if seed.size else None)
        if version >= 2:
            prior = np.asarray(arrays["covars_prior"], dtype=np.float64)
            model.covars_prior = prior if prior.size else None
            model.covars_weight = float(arrays["covars_weight"])
        if version >= 3:
            model.mean_model = str(arrays["mean_model"])
            model.smoothing = float(arrays["smoothing"])
            model.max_centres = int(arrays["max_centres"])
        model._check_params()
        k = model.n_states
        mean_bar = _entry(arrays, "mean_bar_", 2, path)
        w = _entry(arrays, "W_", 3, path)
        train_key = _TRAIN_PHI_ENTRY[version]
        train = _entry(arrays, train_key, 2, path)
        d, p = mean_bar.shape[1], w.shape[2]
        try:
            model._prior_variances(d)
        except InvalidInputError as exc:
            raise DataFileError(f"{path}: entry covars_prior is malformed ({exc})") from exc
        cov_shape = (k, d, d) if model.covariance_type == "full" else (k, d)
        learned = {
            "startprob_": (_entry(arrays, "startprob_", 1, path), (k,)),
            "transmat_": (_entry(arrays, "transmat_", 2, path), (k, k)),
            "mean_bar_": (mean_bar, (k, d)),
            "W_": (w, (k, d, p)),
            "covars_": (_entry(arrays, "covars_", len(cov_shape), path), cov_shape),
            train_key: (train, (train.shape[0], p)),
        }
        if version >= 3:
            bend = _entry(arrays, "V_", 3, path)
            m = bend.shape[2]
            learned["V_"] = (bend, (k, d, m))
            learned["feature_centres_"] = (_entry(arrays, "feature_centres_", 2, path), (m, p))
            learned["feature_low_"] = (_entry(arrays, "feature_low_", 1, path), (p,))
            learned["feature_span_"] = (_entry(arrays, "feature_span_", 1, path), (p,))
        else:
            learned["V_"] = (np.zeros((k, d, 0)), (k, d, 0))
        for name, (value, shape) in learned.items():
            if value.shape != shape or not np.all(np.isfinite(value)):
                raise DataFileError(f"{path}: entry {name} has shape {value.shape}, expected {shape} and finite")
            setattr(model, "train_phi_" if name == train_key else name, value)
        model.effect_features_ = _features_from_entries(model, path)
        check_learned_meaning(model, path)
        history = _entry(arrays, "log_likelihood_history_", 1, path)
        converged = bool(arrays["converged_"])
    except KeyError as exc:
        raise DataFileError(f"{path}: entry {exc} is missing; {_ACCEPTED_FILES}") from exc
    except (IndexError, TypeError, ValueError) as exc:
        raise DataFileError(f"{path}: missing or malformed entry ({exc})") from exc
    model.n_features_in_ = d
    model.phi_dim_ = p
    model.log_likelihood_history_ = history
    model.converged_ = converged
    return model

def check_learned_meaning(model: Any, path: Path) -> None:
    """Raise DataFileError naming ``path`` and the entry if the learned values are not a valid HMM.

    Shapes and finiteness are checked already; this checks what EM always produces: probability
    distributions, symmetric positive definite covariances, and the transitions the topology allows.
    """
    def bad(name: str, problem: str, accepted: str) -> DataFileError:
        return DataFileError(f"{path}: entry {name} {problem}; accepted: {accepted}")

    if model.train_phi_.shape[0] == 0:
        raise bad("train_phi_", "is empty", "the (S, p) effects of the S >= 1 training sequences")
    start, trans = model.startprob_, model.transmat_
    if np.any(start < 0) or abs(start.sum() - 1.0) > _PROBABILITY_TOLERANCE:
        raise bad("startprob_", f"is not a probability distribution (sum {start.sum():.6g}, smallest "
                  f"{start.min():.6g})", f"non-negative values summing to 1 (within {_PROBABILITY_TOLERANCE})")
    row_sums = trans.sum(axis=1)
    wrong = np.flatnonzero(np.any(trans < 0, axis=1) | (np.abs(row_sums - 1.0) > _PROBABILITY_TOLERANCE))
    if wrong.size:
        i = int(wrong[0])
        raise bad("transmat_", f"row {i} is not a probability distribution (sum {row_sums[i]:.6g}, smallest "
                  f"{trans[i].min():.6g}; {wrong.size} bad row(s))",
                  f"non-negative rows each summing to 1 (within {_PROBABILITY_TOLERANCE})")
    if model._left_right:
        reach = 2 if model.topology == "left-right-skip" else 1
        offsets = np.subtract.outer(np.arange(model.n_states), np.arange(model.n_states))  # i - j
        if start[0] < 1.0 - _PROBABILITY_TOLERANCE or np.any(trans[(offsets > 0) | (offsets < -reach)] != 0):
            raise bad("transmat_/startprob_", f"break the {model.topology} chain",
                      f"a chain that starts in state 0 and only stays or moves right by at most {reach} "
                      f"state(s), as training a {model.topology} model gives")
    covars = model.covars_
    if model.covariance_type == "full":
        asymmetry = np.abs(covars - covars.transpose(0, 2, 1)).max()
        if asymmetry > _SYMMETRY_TOLERANCE * max(np.abs(covars).max(), 1.0):
            raise bad("covars_", f"holds a non-symmetric matrix (largest asymmetry {asymmetry:.3g})",
                      "symmetric positive definite covariance matrices")
    try:
        precision_cholesky(covars, model.covariance_type)
    except InvalidInputError as exc:
        raise bad("covars_", "holds a covariance that is not positive definite",
                  "symmetric positive definite covariance matrices ('full') or variances > 0 ('diag')") from exc




def _read_npz(path: Path) -> dict[str, np.ndarray]:
    """Every entry of the ``.npz`` archive ``path`` as an array, never unpickling anything.

    Other files are told apart by their first bytes first, so the error says what the file looks
    like instead of numpy's guess that it might be pickled data.
    """
    checked_input_file(path, "ParametricHMM file", MAX_NPZ_BYTES)
    try:
        with open(path, "rb") as fh:
            head = fh.read(_SNIFF_BYTES)
    except OSError as exc:
        raise DataFileError(f"could not read model file {path}: {exc}") from exc
    if not head.startswith(_ZIP_SIGNATURES):
        raise DataFileError(f"{path} is not a ParametricHMM file: it looks like {_describe_file(head)}; "
                            f"{_ACCEPTED_FILES}")
    arrays: dict[str, np.ndarray] = {}
    try:
        _check_declared_sizes(path)
        with np.load(path, allow_pickle=False) as data:
            for key in data.files:
                try:
                    arrays[key] = np.asarray(data[key])
                except ValueError as exc:  # an object array: numpy would need to unpickle it
                    raise DataFileError(f"{path}: entry {key} holds Python objects, not a plain numeric or text "
                                        f"array; {_ACCEPTED_FILES}, whose entries never hold objects") from exc
    except DataFileError:
        raise
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError) as exc:
        raise DataFileError(f"{path} is not a readable ParametricHMM .npz file (truncated or corrupt?): {exc}") from exc
    return arrays


def _check_declared_sizes(path: Path) -> None:
    """Refuse an archive whose entries' headers declare more than :data:`MAX_ARRAY_BYTES` in all: numpy
    would try to allocate it before finding the data missing."""
    declared = 0
    with zipfile.ZipFile(path) as archive:
        for member in archive.infolist():
            with archive.open(member) as stream:
                version = np.lib.format.read_magic(stream)
                read_header = _HEADER_READERS.get(version)
                if read_header is None:
                    raise DataFileError(f"{path}: entry {member.filename} is a .npy of version {version}; "
                                        f"{_ACCEPTED_FILES} (versions {sorted(_HEADER_READERS)})")
                shape, _, dtype = read_header(stream)
            declared += int(np.prod(shape, dtype=object)) * dtype.itemsize
            if declared > MAX_ARRAY_BYTES:
                raise DataFileError(f"{path}: entry {member.filename} declares arrays of {declared / 2**30:.1f} GiB "
                                    f"in all, more than a ParametricHMM has ({MAX_ARRAY_BYTES / 2**30:.0f} GiB at "
                                    f"most); {_ACCEPTED_FILES}")


def _describe_file(head: bytes) -> str:
    """What a file that is not a zip archive looks like, from its first bytes."""
    if not head:
        return "an empty file"
    for signature, description in _OTHER_SIGNATURES:
        if head.startswith(signature):
            return description
    if head.lstrip()[:1] in (b"{", b"["):
        return "a JSON document (such as a PrimitiveDiscovery or ActionGrammar model)"
    return f"no format hoap_actions writes (it starts with {head!r})"


def _entry(arrays: Mapping[str, np.ndarray], name: str, ndim: int, path: Path) -> np.ndarray:
    """The learned array ``name`` as float64 with ``ndim`` axes, or a DataFileError naming it."""
    if name not in arrays:
        raise DataFileError(f"{path}: entry {name} is missing; {_ACCEPTED_FILES}")
    value = arrays[name]
    if value.dtype.kind not in "biuf" or value.ndim != ndim:
        raise DataFileError(f"{path}: entry {name} is a {value.ndim}-D {value.dtype} array; accepted: a "
                            f"{ndim}-D numeric array")
    return value.astype(np.float64)


def _features_from_entries(model: Any, path: Path) -> ThinPlateFeatures:
    """The thin-plate features a loaded model's entries describe (none for linear models and old files),
    or DataFileError if they contradict its mean model or are not usable features."""
    p, m = model.W_.shape[2], model.V_.shape[2]
    if not hasattr(model, "feature_centres_"):
        return ThinPlateFeatures.none(p)
    features = ThinPlateFeatures(model.__dict__.pop("feature_centres_"), model.__dict__.pop("feature_low_"),
                                 model.__dict__.pop("feature_span_"))
    if (model.mean_model == "linear" and m > 0) or (model.mean_model == "tps" and m == 0 and p > 0):
        raise DataFileError(f"{path}: entry V_ has {m} feature column(s) but mean_model is {model.mean_model!r}; "
                            "accepted: none for 'linear' (or an effect of size 0), one per thin-plate centre for 'tps'")
    try:
        features.check(p)
    except InvalidInputError as exc:
        raise DataFileError(f"{path}: entries feature_centres_/feature_low_/feature_span_ are malformed "
                            f"({exc})") from exc
    return features

