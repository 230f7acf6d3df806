"""Robot episodes as Minari datasets, read back with Minari itself and replayed in a fresh env."""

from __future__ import annotations

import numpy as np
import pytest

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.apps.cli import main
from hoap_actions.apps.collect import collect
from hoap_actions.errors import HoapActionsError, InvalidInputError

minari = pytest.importorskip("minari")
DATASET = "hoap_actions/PegInsert/scripted-v0"


@pytest.fixture(scope="module")
def datasets_root(tmp_path_factory):
    root = tmp_path_factory.mktemp("minari")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("MINARI_DATASETS_PATH", str(root))
        collect("hoap_actions/PegInsert-v0", "scripted", 2, 7, DATASET)
        yield root


def test_minari_reads_the_episodes_and_recovers_the_env(datasets_root, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(datasets_root))
    dataset = minari.load_dataset(DATASET)
    assert dataset.total_episodes == 2
    episodes = list(dataset.iterate_episodes())
    assert [e.id for e in episodes] == [0, 1]
    for episode in episodes:
        assert episode.terminations[-1] or episode.truncations[-1]
        assert len(episode.actions) == len(episode.rewards) == len(episode.observations["observation"]) - 1
    env = dataset.recover_environment()
    assert env.spec.id == "hoap_actions/PegInsert-v0" and env.unwrapped.control_mode == "ee_delta"
    env.close()


def test_an_episodes_actions_replayed_in_a_fresh_env_give_its_observations(datasets_root, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(datasets_root))
    dataset = minari.load_dataset(DATASET)
    episode = next(dataset.iterate_episodes([0]))
    env = dataset.recover_environment()
    try:
        obs, _ = env.reset(seed=7)  # the collector's first seed
        replayed = [obs["observation"]]
        for action in episode.actions:
            obs, *_ = env.step(action)
            replayed.append(obs["observation"])
    finally:
        env.close()
    np.testing.assert_array_equal(np.array(replayed), episode.observations["observation"])


def test_an_existing_dataset_is_kept_unless_asked(datasets_root, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(datasets_root))
    with pytest.raises(HoapActionsError, match="already exists"):
        collect("hoap_actions/PegInsert-v0", "scripted", 1, 0, DATASET)
    assert minari.load_dataset(DATASET).total_episodes == 2


def test_bad_ids_and_policies_are_refused_before_any_episode(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    with pytest.raises(InvalidInputError, match="not a Minari id"):
        collect("hoap_actions/PegInsert-v0", "scripted", 1, 0, "no version")
    assert main(["collect", "--policy", "scripted", "--env", "hoap_actions/Reach-v1", "--dataset-id", "a/b-v0"]) == 2
    assert "does not act in hoap_actions/Reach-v1" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


def test_a_welded_legs_dataset_recovers_that_robot(tmp_path, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    collect("hoap_actions/PegInsert-v0", "scripted", 1, 3, "hoap_actions/PegInsert/fixed-legs-v0", robot="fixed_legs")
    dataset = minari.load_dataset("hoap_actions/PegInsert/fixed-legs-v0")
    env = dataset.recover_environment()
    try:
        assert env.unwrapped.robot.fixed_legs
        episode = next(dataset.iterate_episodes([0]))
        obs, _ = env.reset(seed=3)
        np.testing.assert_array_equal(obs["observation"], episode.observations["observation"][0])
    finally:
        env.close()
    with pytest.raises(InvalidInputError, match="fixed_legs"):
        collect("hoap_actions/PegInsert-v0", "scripted", 1, 0, "hoap_actions/PegInsert/bad-v0", robot="wheels")
