"""What two sub-envs in lockstep can gain on two cores, against what two independent envs gain: the
ceiling under ``benchmarks/vector_envs.py``'s ratios.

A vector env steps its sub-envs together: each ``step`` waits for the slower one and pays an exchange
between processes. Four ways of stepping ``PegInsert-v0`` (random actions, the same seeds, each from a
fresh ``reset``), taking turns ``--runs`` times:

- ``one``: one env in this process (the reference);
- ``independent``: two processes, pinned one to each core, each stepping its own env with no exchange
  at all (what the machine gives two envs that never wait for each other);
- ``hybrid``: the package's :class:`~hoap_actions.envs.vector.HybridVectorEnv` (sub-env 0 here, 1 in a
  worker);
- ``spin``: the cheapest lockstep this probe knows: this process and one worker, pinned, exchanging
  actions and results through shared memory and busy-waiting for each other (no pipe, no sleep), so
  what is left is the lockstep itself.

Ratios are env steps per wall second against ``one``. Linux only (pinning), at least 2 cores.

    python benchmarks/lockstep_limit.py [--robot fixed_legs] [--control-mode joint_delta] [--runs 3]

Writes ``results/lockstep_limit.json``.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import pickle
import statistics
import sys
import time
from multiprocessing import shared_memory
from pathlib import Path

import gymnasium
import numpy as np

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.envs.robot import ROBOT_MODELS
from hoap_actions.envs.vector import make_hybrid

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json

ENV_ID = "hoap_actions/PegInsert-v0"
_CONTROL, _ACTIONS, _RESULT = 0, 64, 1024  # shared-memory layout of the spin exchange (bytes)
_STEP, _STOP = 1, 2


def _stepped(env: gymnasium.Env, actions: list[np.ndarray]) -> float:
    """Wall seconds to step ``env`` through ``actions`` (resetting at episode ends)."""
    start = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return time.perf_counter() - start


def _env_and_actions(seed: int, steps: int, kwargs: dict) -> tuple[gymnasium.Env, list[np.ndarray]]:
    env = gymnasium.make(ENV_ID, **kwargs)
    env.reset(seed=seed)
    env.action_space.seed(seed)
    return env, [env.action_space.sample() for _ in range(steps)]


def one(seed: int, steps: int, kwargs: dict) -> float:
    env, actions = _env_and_actions(seed, steps, kwargs)
    elapsed = _stepped(env, actions)
    env.close()
    return steps / elapsed


def _independent_worker(core: int, seed: int, steps: int, kwargs: dict, barrier, results) -> None:
    os.sched_setaffinity(0, {core})
    env, actions = _env_and_actions(seed, steps, kwargs)
    barrier.wait()
    results.put(_stepped(env, actions))
    env.close()


def independent(seed: int, steps: int, kwargs: dict) -> float:
    context = mp.get_context("spawn")
    barrier, results = context.Barrier(2), context.Queue()
    workers = [context.Process(target=_independent_worker, args=(core, seed + core, steps, kwargs, barrier, results))
               for core in (0, 1)]
    for worker in workers:
        worker.start()
    slower = max(results.get(), results.get())
    for worker in workers:
        worker.join()
    return 2 * steps / slower


def hybrid(seed: int, steps: int, kwargs: dict) -> float:
    envs = make_hybrid(ENV_ID, 2, **kwargs)
    envs.reset(seed=seed)
    envs.action_space.seed(seed)
    actions = [envs.action_space.sample() for _ in range(steps)]
    start = time.perf_counter()
    for action in actions:
        envs.step(action)
    elapsed = time.perf_counter() - start
    envs.close()
    return 2 * steps / elapsed


def _spin_worker(name: str, seed: int, kwargs: dict) -> None:
    os.sched_setaffinity(0, {1})
    memory = shared_memory.SharedMemory(name=name)
    control = np.ndarray((4,), dtype=np.int64, buffer=memory.buf, offset=_CONTROL)  # asked, answered, length, ready
    env = gymnasium.make(ENV_ID, **kwargs)
    env.reset(seed=seed)
    actions = np.ndarray(env.action_space.shape, dtype=np.float64, buffer=memory.buf, offset=_ACTIONS)
    control[3] = 1
    answered = 0
    while True:
        while control[0] == answered:  # busy-wait: no sleep, no wake-up
            pass
        answered = int(control[0])
        if answered < 0:
            break
        result = env.step(actions.copy())
        if result[2] or result[3]:
            env.reset()
        payload = pickle.dumps(result, protocol=pickle.HIGHEST_PROTOCOL)
        memory.buf[_RESULT: _RESULT + len(payload)] = payload
        control[2] = len(payload)
        control[1] = answered
    del control, actions
    env.close()
    memory.close()


def spin(seed: int, steps: int, kwargs: dict) -> float:
    cores = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {0})
    memory = shared_memory.SharedMemory(create=True, size=1 << 20)
    worker = None
    try:
        control = np.ndarray((4,), dtype=np.int64, buffer=memory.buf, offset=_CONTROL)
        control[:] = 0
        worker = mp.get_context("spawn").Process(target=_spin_worker, args=(memory.name, seed + 1, kwargs))
        worker.start()
        env, actions = _env_and_actions(seed, steps, kwargs)
        remote = np.ndarray(env.action_space.shape, dtype=np.float64, buffer=memory.buf, offset=_ACTIONS)
        others = [env.action_space.sample() for _ in range(steps)]
        while control[3] == 0:  # the worker's env is built
            time.sleep(0.01)
        start = time.perf_counter()
        for asked, (action, other) in enumerate(zip(actions, others), start=1):
            remote[:] = other
            control[0] = asked
            local = env.step(action)
            if local[2] or local[3]:
                env.reset()
            while control[1] != asked:
                pass
            answer = pickle.loads(memory.buf[_RESULT: _RESULT + int(control[2])])
            batch = {key: np.stack([local[0][key], answer[0][key]]) for key in local[0]}  # as a vector env does
        elapsed = time.perf_counter() - start
        assert all(len(value) == 2 for value in batch.values())
        control[0] = -1
        worker.join()
        env.close()
        del control, remote
        return 2 * steps / elapsed
    finally:
        if worker is not None and worker.is_alive():
            worker.terminate()
        os.sched_setaffinity(0, cores)  # this process's own cores again
        memory.close()
        memory.unlink()


KINDS = {"one": one, "independent": independent, "hybrid": hybrid, "spin": spin}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0], parents=[arguments("lockstep_limit.json")])
    parser.add_argument("--robot", choices=list(ROBOT_MODELS), default="fixed_legs")
    parser.add_argument("--control-mode", choices=["joint_delta", "ee_delta"], default="joint_delta")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--steps", type=int, default=300)
    args = parser.parse_args()
    if not hasattr(os, "sched_setaffinity") or len(os.sched_getaffinity(0)) < 2:
        parser.error("needs Linux and at least 2 cores to pin the two envs to")
    if args.runs < 1 or args.steps < 1:
        parser.error("--runs and --steps must be >= 1")
    kwargs = {"robot": args.robot, "control_mode": args.control_mode}
    rates: dict[str, list[float]] = {kind: [] for kind in KINDS}
    for run in range(args.runs):
        for kind, measure in KINDS.items():
            rates[kind].append(measure(run, args.steps, kwargs))
        print(f"run {run}: " + ", ".join(f"{kind} {rates[kind][-1]:.0f}" for kind in KINDS) + " steps/s", flush=True)
    reference = statistics.median(rates["one"])
    summary = {kind: {"steps_per_s": statistics.median(values), "runs": values,
                      "ratio": statistics.median(values) / reference,
                      "run_ratios": [value / base for value, base in zip(values, rates["one"])]}
               for kind, values in rates.items()}
    print(", ".join(f"{kind} {row['ratio']:.2f}x" for kind, row in summary.items()))
    write_json(args.output, {"benchmark": "lockstep_limit", **kwargs, "runs": args.runs, "steps": args.steps,
                             "kinds": summary, "environment": numeric_environment(None)})


if __name__ == "__main__":
    main()
