"""Speed of retiming: one streaming step (goal: tens of microseconds) and one 200-point hand path.

Medians of one :class:`StreamingRetimer` step (3 DOF with a moving and with a fixed target, 14 DOF
with a moving one; 20 000 steps each) and of :func:`retime_path` on a 200-point hand path (200
repeats), at the hand's limits (0.5 m/s, 2 m/s^2, 20 m/s^3).

    python benchmarks/retiming_speed.py

Prints the medians and writes ``results/retiming_speed.json``; earlier figures are in ``docs/experiments/speed.md``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import ruckig

from hoap_actions.controllers.retiming import DEFAULT_DT, StreamingRetimer, retime_path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json

HAND_LIMITS = (0.5, 2.0, 20.0)  # m/s, m/s^2, m/s^3


def _median_us(samples_ns: list[int]) -> float:
    return float(np.median(samples_ns)) / 1e3


def bench_streaming_step(n_dof: int, moving: bool, steps: int = 20_000) -> float:
    """Median time of one step; a moving target makes ruckig recalculate every cycle (the worst case)."""
    retimer = StreamingRetimer(n_dof, DEFAULT_DT, *HAND_LIMITS)
    retimer.reset(np.zeros(n_dof))
    phases = np.arange(n_dof)
    times = []
    for k in range(steps):
        target = 0.1 * np.sin(k / 50 + phases) if moving else np.full(n_dof, 0.1)
        start = time.perf_counter_ns()
        retimer.step(target)
        times.append(time.perf_counter_ns() - start)
    return _median_us(times)


def bench_retime_path(points: int = 200, repeats: int = 200) -> tuple[float, float, int]:
    """Median time to retime a hand path (a lifted reach with a curl) of ``points`` points."""
    tau = np.linspace(0.0, 1.0, points)
    path = np.stack(
        [0.1 + 0.15 * tau, 0.08 * np.sin(np.pi * tau), 0.02 + 0.06 * np.sin(np.pi * tau) ** 2], axis=-1
    )
    times = []
    for _ in range(repeats):
        start = time.perf_counter_ns()
        timed = retime_path(path, *HAND_LIMITS)
        times.append(time.perf_counter_ns() - start)
    return _median_us(times), float(timed.t[-1]), int(timed.t.size)


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], parents=[arguments("retiming_speed.json")])
    args = parser.parse_args(argv)
    step_moving_3 = bench_streaming_step(3, moving=True)
    step_fixed_3 = bench_streaming_step(3, moving=False)
    step_moving_14 = bench_streaming_step(14, moving=True)
    path_us, duration, samples = bench_retime_path()
    results = {
        "streaming_step_us_median": {
            "3dof_moving_target": step_moving_3,
            "3dof_fixed_target": step_fixed_3,
            "14dof_moving_target": step_moving_14,
        },
        "retime_200_point_hand_path_us_median": path_us,
        "retimed_path_duration_s": duration,
        "retimed_path_samples": samples,
        "dt_s": DEFAULT_DT,
        "limits_v_a_j": list(HAND_LIMITS),
        "environment": numeric_environment(blas_threads=None, ruckig=ruckig.__version__),
    }
    print(f"streaming step, 3 DOF, moving target:  {step_moving_3:8.1f} us (median)")
    print(f"streaming step, 3 DOF, fixed target:   {step_fixed_3:8.1f} us (median)")
    print(f"streaming step, 14 DOF, moving target: {step_moving_14:8.1f} us (median)")
    print(f"retime 200-point hand path:            {path_us:8.1f} us (median; {duration:.3f} s, {samples} samples)")
    write_json(args.output, results)
    return results


if __name__ == "__main__":
    main()
