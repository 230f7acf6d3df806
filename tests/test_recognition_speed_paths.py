"""Recognition's fast paths give what the plain computations give: the effects of many (model, movement)
pairs estimated in one batch, its log-space forward-backward on chains laid end to end, the elementwise
paths of diagonal covariances, demonstrations and movements decoded in batches, and the recognition
report's figures whatever the number of worker processes."""

from __future__ import annotations

import os

import numpy as np
import pytest

from hoap_actions import parallel
from hoap_actions.errors import InvalidInputError
from hoap_actions.models.shipped import load_default_models
from hoap_actions.primitives.discovery.estimator import UNKNOWN
from hoap_actions.primitives.hmm import hmm_math, phi_estimates
from hoap_actions.primitives.hmm.parametric_hmm import ParametricHMM
from hoap_actions.primitives.hmm.phi_estimates import estimate_phis
from hoap_actions.primitives.hmm.phmm_batch import SequenceBatch
from hoap_actions.primitives.hmm.phmm_effects import phi_update
from hoap_actions.primitives.labels import runs
from hoap_actions.primitives.pipelines import recognize

D = 3  # features per frame of the synthetic classes


def _fitted(seed: int, n_states: int, p: int, sd: float, topology: str = "left-right") -> ParametricHMM:
    """A diagonal-covariance PHMM fitted on sequences of a known linear class with ``p`` effect dimensions."""
    rng = np.random.default_rng(seed)
    mean_bar = np.cumsum(rng.normal(size=(n_states, D)), axis=0)
    w = rng.normal(scale=0.5, size=(n_states, D, p))
    phis = rng.uniform(-1, 1, size=(20, p))
    durations = 1 + rng.geometric(0.25, size=(20, n_states))
    sequences = [(mean_bar + w @ phi)[np.repeat(np.arange(n_states), d)] for phi, d in zip(phis, durations)]
    X = np.concatenate(sequences) + sd * rng.normal(size=(durations.sum(), D))
    return ParametricHMM(n_states=n_states, topology=topology, covariance_type="diag", n_iter=30,
                         random_state=seed).fit(X, durations.sum(axis=1), phis)


def _movement(model: ParametricHMM, seed: int, frames_per_state: int) -> np.ndarray:
    """A movement the model's chain can explain: its means at a random effect, held and jittered."""
    rng = np.random.default_rng(seed)
    phi = rng.uniform(-1, 1, size=model.phi_dim_)
    means = model.mean_bar_ + model.W_ @ phi
    X = np.repeat(means, frames_per_state, axis=0)
    return X + np.sqrt(model.covars_.mean()) * rng.normal(size=X.shape)


@pytest.fixture(scope="module")
def classes():
    """Two broad classes (4 states, 2-D effect; 3 states, 1-D effect) and a sharp one (variances of 1e-8)."""
    return _fitted(1, 4, 2, 0.05), _fitted(2, 3, 1, 0.05), _fitted(3, 5, 2, 1e-4)


@pytest.fixture(scope="module")
def jobs(classes):
    """Pairs of every class with movements of several lengths, some under a class that did not make them."""
    broad, narrow, sharp = classes
    pairs = [(model, _movement(maker, seed, frames))
             for seed, (model, maker, frames) in enumerate([(broad, broad, 3), (narrow, narrow, 7), (broad, broad, 9),
                                                            (sharp, sharp, 4), (narrow, broad, 2), (sharp, sharp, 11),
                                                            (broad, narrow, 5), (narrow, narrow, 1)])]
    return [(model, X) for model, X in pairs if len(X) >= model.min_frames]


@pytest.mark.parametrize("n_restarts", [1, 3])
def test_a_batch_gives_each_pair_the_effect_estimate_phi_gives(jobs, n_restarts):
    batched = estimate_phis(jobs, n_restarts=n_restarts)
    for (model, X), phi in zip(jobs, batched):
        np.testing.assert_allclose(phi, model.estimate_phi(X, n_restarts=n_restarts), rtol=1e-7, atol=1e-9)


def test_the_pairs_beside_it_do_not_change_a_pairs_effect(jobs):
    alone = [estimate_phis([job], n_restarts=1)[0] for job in jobs]
    for phi, own in zip(estimate_phis(jobs, n_restarts=1), alone):
        np.testing.assert_allclose(phi, own, rtol=1e-12, atol=1e-14)


def test_log_space_chains_give_forward_backwards_posteriors_where_scaled_probabilities_underflow(classes):
    """Chains of different sizes and lengths end to end; emissions spread over thousands of nats."""
    rng = np.random.default_rng(4)
    lengths, transitions, references, blocks = np.array([40, 25, 25, 6]), [], [], []
    for size, length in zip((5, 3, 1, 6), lengths):
        stay = rng.uniform(0.3, 0.9, size)
        transmat = np.diag(stay) + np.diag(1 - stay[:-1], 1)
        transmat[-1, -1] = 1.0
        logb = rng.normal(scale=300.0, size=(length, size))
        with np.errstate(divide="ignore"):
            log_a, log_start = np.log(transmat), np.log(np.eye(size)[0])
        transitions.append((np.diagonal(log_a).copy(), np.append(np.diagonal(log_a, 1), -np.inf)))
        end = np.full(size, -np.inf)
        end[-1] = 0.0
        references.append(hmm_math.forward_backward(log_start, log_a, logb, [length], end))
        blocks.append(logb)
    chains = phi_estimates._Chains.build(lengths, transitions)
    logb = np.zeros((lengths[0], int(chains.sizes.sum())))
    for first, block in zip(chains.first, blocks):
        logb[:len(block), first:first + block.shape[1]] = block
    ll, gamma = chains.posteriors(logb)
    for row, (ll_ref, gamma_ref, _) in enumerate(references):
        first, size, length = chains.first[row], chains.sizes[row], lengths[row]
        assert ll[row] == pytest.approx(ll_ref[0], rel=1e-12)
        np.testing.assert_allclose(gamma[:length, first:first + size], gamma_ref, rtol=1e-9, atol=1e-12)
        assert not gamma[length:, first:first + size].any()


def test_estimate_phis_refuses_what_it_cannot_run(classes):
    broad = classes[0]
    skip = _fitted(5, 4, 2, 0.05, topology="left-right-skip")
    with pytest.raises(InvalidInputError, match="left-right chains only"):
        estimate_phis([(skip, _movement(skip, 0, 3))])
    with pytest.raises(InvalidInputError, match="n_restarts"):
        estimate_phis([(broad, _movement(broad, 0, 3))], n_restarts=0)
    with pytest.raises(InvalidInputError, match="frames"):
        estimate_phis([(broad, _movement(broad, 0, 3)[:2])])
    assert estimate_phis([]) == []


def test_diagonal_covariances_take_elementwise_paths_with_the_full_paths_numbers(classes, jobs):
    model, X = jobs[0]
    full = ParametricHMM(n_states=model.n_states, covariance_type="full")
    full.__dict__.update({k: v for k, v in model.__dict__.items() if k.endswith("_")},
                         covariance_type="full", covars_=np.stack([np.diag(v) for v in model.covars_]))
    phis = model._restart_phis(3)
    batches = [SequenceBatch.build(np.tile(X, (3, 1)), np.full(3, len(X)), phis, model.mean_bar_.mean(axis=0), kind)
               for kind in ("diag", "full")]
    densities = [hmm_math.log_gaussian_density_padded(b.X, m._means_at(b.phi, b.offset), m.covars_,
                                                      m.covariance_type, b.moments)
                 for m, b in zip((model, full), batches)]
    np.testing.assert_allclose(densities[0], densities[1], rtol=1e-10)
    gamma = np.random.default_rng(0).dirichlet(np.ones(model.n_states), size=(3, len(X)))
    np.testing.assert_allclose(phi_update(model, batches[0], gamma), phi_update(full, batches[1], gamma),
                               rtol=1e-9)


@pytest.fixture(scope="module")
def shipped(small_demos):
    """The shipped models, the ``small`` recording and discovery's cut of each of its episodes."""
    models = load_default_models()
    truth = models.discovery_.predict(np.concatenate([e.O for e in small_demos]), [e.T for e in small_demos])
    cuts = [[(c, a, b) for c, a, b in runs(labels) if c != UNKNOWN] for labels in truth]
    return models, small_demos, cuts


def test_demonstrations_decoded_together_as_each_on_its_own(shipped):
    models, demos, cuts = shipped
    pieces = [[episode.H[a:b] for _, a, b in cut] for episode, cut in zip(demos, cuts) if cut]
    for together, pieces_of_one in zip(models.decode_demonstrations(pieces), pieces):
        alone = models.decode_segments(pieces_of_one)
        assert [r.class_id for r in together] == [r.class_id for r in alone]
        for a, b in zip(together, alone):
            np.testing.assert_allclose(a.phi, b.phi, rtol=1e-9)
            assert a.phis.keys() == b.phis.keys()


def test_movements_decoded_together_as_each_on_its_own(shipped):
    models, demos, _ = shipped
    movements = [(X, models.connected_log_emissions(X)) for X in (models.features(e.H) for e in demos)]
    for together, (X, log_emissions) in zip(models.decode_movements(movements), movements):
        alone = models.decode_features(X, log_emissions)
        assert [(s.class_id, s.start, s.end) for s in together] == [(s.class_id, s.start, s.end) for s in alone]
        for a, b in zip(together, alone):
            np.testing.assert_allclose(a.phi, b.phi, rtol=1e-9)


def test_the_recognition_figures_do_not_depend_on_the_worker_processes(shipped, monkeypatch):
    models, demos, _ = shipped
    monkeypatch.setattr(recognize, "EPISODES_PER_JOB", 1)  # the episodes spread over both workers
    one, two = (recognize.recognize_recording(models, demos, jobs=jobs) for jobs in (1, 2))
    timings = {"wall_s", "decode_s", "jobs"}
    assert {k: v for k, v in one.items() if k not in timings} == {k: v for k, v in two.items() if k not in timings}
    assert one["oracle_cut_accuracy"] is not None and one["episodes"] == len(demos)


def test_workers_are_given_one_blas_thread_unless_the_environment_says_otherwise(monkeypatch):
    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    for name in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        monkeypatch.delenv(name, raising=False)
    with parallel._one_blas_thread_per_worker():
        assert (os.environ["OPENBLAS_NUM_THREADS"], os.environ["MKL_NUM_THREADS"]) == ("1", "1")
        assert os.environ["OMP_NUM_THREADS"] == "3"
    assert "OPENBLAS_NUM_THREADS" not in os.environ and "MKL_NUM_THREADS" not in os.environ
    assert os.environ["OMP_NUM_THREADS"] == "3"
