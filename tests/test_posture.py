"""PostureModel: shoulder and elbow from the hand (ridge on polynomial features), its penalty choice and its file."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hoap_actions.errors import DataFileError, InvalidInputError, NotFittedError
from hoap_actions.primitives.hmm.posture import COMPLETED, PostureModel, choose_alpha, hand_inputs


def arm_frames(n: int, seed: int = 0, arm=None) -> np.ndarray:
    """``(n, 18)`` marker frames: hands scattered over a table-top region, shoulder and elbow given by
    ``arm(inputs)`` (default: a smooth nonlinear function of the hand)."""
    rng = np.random.default_rng(seed)
    wrist = rng.uniform([0.1, -0.4, 0.0], [0.5, 0.4, 0.2], size=(n, 3))
    knuckle = wrist + 0.08 * _unit(rng.normal(size=(n, 3)))
    thumb = wrist + 0.06 * _unit(rng.normal(size=(n, 3)))
    index = knuckle + 0.04 * _unit(rng.normal(size=(n, 3)))
    X = np.zeros((n, 6, 3))
    X[:, 2], X[:, 3], X[:, 4], X[:, 5] = wrist, index, knuckle, thumb
    u = hand_inputs(X.reshape(n, 18))
    arm = arm or (lambda u: np.column_stack([u[:, :3] * [0.3, 0.5, 0.2] + u[:, 3:6] ** 2 * 0.01,
                                             u[:, :3] ** 2 + 0.05 * u[:, 6:9]]))
    X[:, :2] = arm(u).reshape(n, 2, 3)
    return X.reshape(n, 18)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_an_arm_that_is_a_polynomial_of_the_hand_is_recovered():
    X = arm_frames(800)  # shoulder and elbow are quadratic in the inputs
    model = PostureModel(degree=2, alpha=1e-9).fit(X)
    test = arm_frames(200, seed=1)
    np.testing.assert_allclose(model.predict(test), test[:, COMPLETED], atol=1e-6)
    too_simple = PostureModel(degree=1, alpha=1e-9).fit(X)
    assert np.abs(too_simple.predict(test) - test[:, COMPLETED]).max() > 1e-3


def test_predictions_match_scikit_learn_scaler_polynomial_ridge():
    sklearn = pytest.importorskip("sklearn")  # installed with hmmlearn, the test extra
    from sklearn.linear_model import Ridge
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import PolynomialFeatures, StandardScaler

    assert sklearn
    X, test = arm_frames(600, arm=lambda u: np.sin(u[:, :6] * 3)), arm_frames(100, seed=2)
    ours = PostureModel(degree=3, alpha=0.3).fit(X).predict(test)
    reference = make_pipeline(StandardScaler(), PolynomialFeatures(3, include_bias=False), Ridge(alpha=0.3))
    theirs = reference.fit(hand_inputs(X), X[:, COMPLETED]).predict(hand_inputs(test))
    np.testing.assert_allclose(ours, theirs, atol=1e-9)


def test_complete_replaces_only_the_shoulder_and_elbow_in_either_layout():
    X = arm_frames(400)
    model = PostureModel(degree=2, alpha=1e-9).fit(X)
    synthesised = arm_frames(50, seed=3)
    wrong = synthesised.copy()
    wrong[:, COMPLETED] += 0.1  # a synthesis whose arm is off by 10 cm
    done = model.complete(wrong)
    np.testing.assert_array_equal(done[:, 6:], wrong[:, 6:])
    np.testing.assert_allclose(done[:, COMPLETED], synthesised[:, COMPLETED], atol=1e-6)
    np.testing.assert_array_equal(model.complete(wrong.reshape(50, 6, 3)), done.reshape(50, 6, 3))
    assert np.all(wrong[:, COMPLETED] == synthesised[:, COMPLETED] + 0.1)  # the input is left alone


def test_choose_alpha_leaves_one_group_out_at_a_time():
    groups = [[arm_frames(120, seed=s)] for s in range(4)]
    alpha, errors = choose_alpha(groups, alphas=(1e-3, 1.0), degree=2)
    assert set(errors) == {1e-3, 1.0} and alpha == min(errors, key=lambda a: (errors[a], -a))
    held_out = groups[0][0]
    model = PostureModel(degree=2, alpha=1.0).fit(np.concatenate([g[0] for g in groups[1:]]))
    fold_error = np.sum((model.predict(held_out) - held_out[:, COMPLETED]) ** 2)
    squared = [fold_error] + [np.sum((PostureModel(degree=2, alpha=1.0).fit(
        np.concatenate([g[0] for j, g in enumerate(groups) if j != k])).predict(groups[k][0])
        - groups[k][0][:, COMPLETED]) ** 2) for k in range(1, 4)]
    assert errors[1.0] == pytest.approx(np.sqrt(sum(squared) / (4 * 120 * 2)))
    with pytest.raises(InvalidInputError, match="at least 2 groups"):
        choose_alpha(groups[:1])


def test_save_and_load_give_the_same_predictions_and_corrupt_files_are_refused(tmp_path):
    model = PostureModel(degree=3, alpha=0.1).fit(arm_frames(500))
    path = tmp_path / "posture.json"
    model.save(path)
    again = PostureModel.load(path)
    test = arm_frames(30, seed=4)
    np.testing.assert_array_equal(again.predict(test), model.predict(test))
    assert again.get_params() == model.get_params()
    document = json.loads(path.read_text())
    document["coef"] = document["coef"][:-1]
    (tmp_path / "short.json").write_text(json.dumps(document))
    with pytest.raises(DataFileError, match="coef must be"):
        PostureModel.load(tmp_path / "short.json")
    document = json.loads(path.read_text())
    document["format_version"] = 2
    (tmp_path / "future.json").write_text(json.dumps(document))
    with pytest.raises(DataFileError, match="format_version 2"):
        PostureModel.load(tmp_path / "future.json")


@pytest.mark.parametrize("params, message", [
    ({"degree": 0}, "degree must be an int from 1 to 5"),
    ({"degree": 2.5}, "degree must be an int"),
    ({"alpha": -1.0}, "alpha must be a finite number > 0"),
    ({"alpha": float("nan")}, "alpha must be a finite number > 0"),
])
def test_bad_hyper_parameters_are_refused(params, message):
    with pytest.raises(InvalidInputError, match=message):
        PostureModel(**params).fit(arm_frames(500))


def test_bad_data_is_refused():
    with pytest.raises(InvalidInputError, match="219 features: it needs more than 219 frames"):
        PostureModel(degree=3).fit(arm_frames(100))
    with pytest.raises(InvalidInputError, match="18 columns"):
        PostureModel().fit(arm_frames(500)[:, :15])
    X = arm_frames(500)
    X[7, 12:15] = X[7, 6:9]  # the knuckle on the wrist
    with pytest.raises(InvalidInputError, match="frame 7: the knuckle or thumb marker is within"):
        PostureModel().fit(X)
    with pytest.raises(NotFittedError):
        PostureModel().predict(arm_frames(5))
    with pytest.raises(InvalidInputError, match="finite marker frames"):
        PostureModel(degree=1).fit(arm_frames(100)).predict(np.full((3, 18), np.nan))
