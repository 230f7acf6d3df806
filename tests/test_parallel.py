"""Sweeps on a local Ray instance give what one process gives: the same episodes, the same file."""

from __future__ import annotations

import sys

import pytest
import ray

from hoap_actions.apps.cli import main
from hoap_actions.apps.episodes import compare_policies, summarise
from hoap_actions.demonstration.recording import record
from hoap_actions.errors import InvalidInputError
from hoap_actions.parallel import check_ray_address, ordered_map

ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])  # Ray's workers cannot import this test module


@pytest.fixture(scope="module")
def local_ray():
    """One Ray instance for the module (two CPUs, as on the CI machine): the sweeps join it."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    yield "local"
    ray.shutdown()


def test_episodes_on_ray_are_the_serial_ones(local_ray):
    policies = {"random": ("random", {})}
    seeds = [3, 4, 5]
    serial = compare_policies("hoap_actions/Reach-v1", policies, seeds)["random"]
    on_ray = compare_policies("hoap_actions/Reach-v1", policies, seeds, workers=2, ray_address=local_ray)["random"]
    assert summarise(on_ray, timings=False) == summarise(serial, timings=False)
    assert [r.seed for r in on_ray] == seeds


def test_recording_on_ray_is_the_same_file_byte_for_byte(local_ray, tmp_path):
    one = record("small", tmp_path / "one.h5", seed=4, progress=False)
    on_ray = record("small", tmp_path / "ray.h5", seed=4, progress=False, workers=2, ray_address=local_ray)
    assert one.read_bytes() == on_ray.read_bytes()


def test_results_come_back_in_job_order(local_ray):
    jobs = list(range(7, 0, -1))  # later jobs finish first: they sleep less
    assert list(ordered_map(_slow_square, jobs, _nothing, (), 3, local_ray)) == [j * j for j in jobs]


def _nothing() -> None:
    """An initializer with nothing to set up."""


def _slow_square(job: int) -> int:
    import time

    time.sleep(0.02 * job)
    return job * job


@pytest.mark.parametrize("address", ["", "   ", None, 3])
def test_an_empty_or_non_text_address_is_refused(address):
    with pytest.raises(InvalidInputError, match="ray address"):
        check_ray_address(address)


def test_cli_refuses_an_empty_address_in_one_line(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["demo", "--episodes", "1", "--ray", ""])
    assert exit_info.value.code == 2
    assert "ray address" in capsys.readouterr().err


def test_without_ray_the_error_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray now fails as if it were not installed
    with pytest.raises(InvalidInputError, match=r"hoap-actions\[ray\]"):
        list(ordered_map(_slow_square, [1], _nothing, (), 2, "local"))


def test_a_ray_that_cannot_be_reached_is_one_clear_error(monkeypatch):
    def unreachable(**kwargs):
        raise ConnectionError("Could not find any running Ray instance.")

    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    monkeypatch.setattr(ray, "init", unreachable)
    with pytest.raises(InvalidInputError, match=r"could not start or join Ray at 'auto' \(ConnectionError"):
        list(ordered_map(_slow_square, [1], _nothing, (), 2, "auto"))
