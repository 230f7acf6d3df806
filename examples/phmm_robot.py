"""The robot does what it learned: the PHMM policy in a plain ``env.step`` loop, and its Fig. 9.

    python examples/phmm_robot.py [--seed 3] [--out out/]

The policy sees the overhead camera and its own joints, never the simulator's poses; it synthesises
approach, move and remove with the shipped models. Writes the Fig. 9 picture (what it located and the
paths it synthesised) and prints how the episode ended.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium
import imageio.v3 as iio

import hoap_actions  # noqa: F401  (registers the hoap_actions/* ids)
from hoap_actions.policies.phmm_policy import PHMMPolicy


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path("out"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    env = gymnasium.make("hoap_actions/PegInsert-v0", control_mode="ee_delta")
    policy = PHMMPolicy(env)  # the shipped models; PHMMPolicy(env, models="out/models") for your own
    obs, info = env.reset(seed=args.seed)
    policy.reset(obs, info)
    for step in range(env.spec.max_episode_steps):  # noqa: B007  (step is read after the loop: steps taken)
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        if terminated or truncated or policy.failure or policy.done:
            break
    print(f"seed {args.seed}: {'success' if info['is_success'] else policy.failure or 'not inserted'} after "
          f"{step + 1} steps; "
          f"largest path deviation {max(policy.path_deviations().values()) * 1000:.1f} mm")
    iio.imwrite(args.out / "fig9.png", policy.figure())
    print(f"wrote {args.out / 'fig9.png'}")
    env.close()


if __name__ == "__main__":
    main()
