"""The plain ``env.step`` loop: random actions on PegInsert, a few frames saved as PNG.

    python examples/random_rollout.py [--out frames/]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium
import imageio.v3 as iio

import hoap_actions  # noqa: F401  (registers the hoap_actions/* ids)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("frames"))
    parser.add_argument("--steps", type=int, default=90)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    env = gymnasium.make("hoap_actions/PegInsert-v0", render_mode="rgb_array", camera="front")
    obs, info = env.reset(seed=args.seed)
    for t in range(args.steps):
        action = env.action_space.sample()
        obs, reward, terminated, truncated, info = env.step(action)
        if t % 30 == 0:
            iio.imwrite(args.out / f"frame_{t:04d}.png", env.render())
        if terminated or truncated:
            obs, info = env.reset()
    env.close()
    print(f"saved frames to {args.out}/, last info: {info}")


if __name__ == "__main__":
    main()
