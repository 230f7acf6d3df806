"""A learning baseline with Stable-Baselines3: SAC with hindsight experience replay on ``Reach-v1`` (ee_delta).

    pip install "hoap-actions[rl]"
    python examples/train_sb3.py [--steps 30000] [--eval-every 10000] [--json out/sb3_reach.json]
    python examples/train_sb3.py --normalize --steps 50000 --save out/reach_policy
    python examples/train_sb3.py --evaluate out/reach_policy --eval-first-seed 80000
    python examples/train_sb3.py --normalize --steps 50000 --residual --residual-scale 0.25 --save out/reach_residual

The last, SAC learning corrections of at most a quarter of an action to the straight-line reach, is the
one that reaches 90 % of fresh layouts within 50k steps (README, "With Stable-Baselines3").

How the envs meet SB3: make them with ``make_vec_env`` (the Gymnasium id and ``env_kwargs``); the
observation is a goal dict, so the policy is ``"MultiInputPolicy"`` and HER
(``HerReplayBuffer``) relabels goals with the env's own ``compute_reward``. SB3's ``check_env``
calls ``compute_reward`` on the object it is given, which Gymnasium 1.x wrappers do not forward: pass
it ``env.unwrapped``. A fall ends an episode and costs a whole episode of -1s, so falling never pays.

Every ``--eval-every`` steps the deterministic policy runs ``--eval-episodes`` layouts from
``--eval-first-seed`` (never used in training) and prints success, falls, training steps and wall
time. The default layouts, 50000-50049, chose the settings here (a validation split); a headline
figure names fresh seeds declared before its run (``docs/experiments/rl.md``). Variants, each
measured there: ``--fields`` (a part of the observation, ``SelectObservation``), ``--gamma``,
``--demo-steps`` (the straight-line reach takes the first steps), ``--residual`` (corrections to it,
``ResidualAction``, ``--residual-scale``), ``--repeat`` (each decision held for several steps, ``RepeatAction``;
``--steps`` still counts the env's steps).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import json
import sys
import time
from pathlib import Path

import gymnasium
import numpy as np

import hoap_actions  # noqa: F401  (registers the hoap_actions/* ids)
from hoap_actions.envs.robot import ROBOT_MODELS
from hoap_actions.envs.wrappers import RepeatAction, ResidualAction, SelectObservation
from hoap_actions.errors import HoapActionsError
from hoap_actions.outputs import claimed_directory, claimed_file
from hoap_actions.policies.registry import StraightReach

VALIDATION_FIRST_SEED = 50000  # the layouts that chose the settings below
CONTROL_MODE = "ee_delta"

SAVED_FILES = ("policy.zip", "normalize.pkl", "settings.json")  # what --save writes
LEARNERS = {"sb3": ("stable_baselines3", "rl"), "sbx": ("sbx", "sbx")}  # --learner: its module and its extra


def make_env(env_id: str, fields: list[str] | None, residual: float = 0.0, repeat: int = 1,
             robot: str = "full") -> gymnasium.Env:
    """The env a policy trains and is evaluated on (``robot``: free-standing or with welded legs): the whole
    observation, or only ``fields`` of it; with ``residual`` > 0, the policy's actions times ``residual`` are
    corrections to the straight-line reach's; each decision held for ``repeat`` steps."""
    env = gymnasium.make(env_id, control_mode=CONTROL_MODE, robot=robot)
    if residual:
        env = ResidualAction(env, StraightReach(env), scale=residual)
    if repeat > 1:
        env = RepeatAction(env, repeat)
    return SelectObservation(env, fields) if fields else env


def evaluate(model, env_id: str, fields: list[str] | None, seeds: range, normalize=lambda obs: obs,
             residual: float = 0.0, repeat: int = 1, robot: str = "full") -> dict:
    env = make_env(env_id, fields, residual, repeat, robot)
    successes = falls = 0
    final_distances = []
    for seed in seeds:
        obs, info = env.reset(seed=seed)
        while True:
            action, _ = model.predict(normalize(obs), deterministic=True)
            obs, reward, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        successes += bool(info["is_success"])
        falls += bool(info["fallen"])
        final_distances.append(float(np.linalg.norm(obs["achieved_goal"] - obs["desired_goal"])))
    env.close()
    return {"success_rate": successes / len(seeds), "falls": falls, "episodes": len(seeds),
            "final_distance_m": final_distances}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="hoap_actions/Reach-v1")
    parser.add_argument("--robot", choices=list(ROBOT_MODELS), default="full",
                        help="the free-standing robot (full, default) or the one with welded legs (fixed_legs)")
    parser.add_argument("--learner", choices=list(LEARNERS), default="sb3",
                        help="whose SAC learns: Stable-Baselines3's (PyTorch, default) or SBX's, the same algorithm "
                             "and settings in JAX (pip install 'hoap-actions[sbx]'; docs/experiments/rl.md)")
    parser.add_argument("--steps", type=int, default=30000)
    parser.add_argument("--eval-every", type=int, default=10000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--eval-first-seed", type=int, default=VALIDATION_FIRST_SEED)
    parser.add_argument("--eval-episodes", type=int, default=50)
    parser.add_argument("--json", type=Path, help="write the learning curve here (claimed before training; "
                        "an existing file is refused unless --overwrite)")
    parser.add_argument("--overwrite", action="store_true")
    parser.add_argument("--fields", nargs="+", metavar="FIELD",
                        help="train on these named fields of the observation only (SelectObservation; e.g. "
                             "tcp_position target peg_positions peg_quaternions hole_positions); default: all of it")
    parser.add_argument("--save", type=Path, help="save the trained policy (and the normalisation statistics) "
                        "in this new directory")
    parser.add_argument("--evaluate", type=Path, metavar="DIR",
                        help="no training: evaluate the policy saved in DIR (by --save) on the evaluation layouts")
    parser.add_argument("--torch-threads", type=int, default=1,
                        help="PyTorch threads (default 1: two runs side by side on 2 cores with PyTorch's default "
                             "threads oversubscribe the cores, docs/experiments/rl.md)")
    parser.add_argument("--gamma", type=float, default=0.95,
                        help="discount factor (0.95 as for Fetch reaches; a reach here takes 40-60 steps at 5 mm each)")
    parser.add_argument("--demo-steps", type=int, default=0, metavar="N",
                        help="Reach-v1: the first N steps (part of --steps) follow the straight-line reference "
                             "(hoap-actions' 'straight' policy) instead of uniform random actions, and learning "
                             "starts after them: demonstrations in the replay buffer")
    parser.add_argument("--residual", action="store_true",
                        help="Reach-v1: the policy learns corrections added to the straight-line reach's actions "
                             "(residual RL; a plain replay buffer, as relabelled goals do not fit the base's actions)")
    parser.add_argument("--residual-scale", type=float, default=1.0, metavar="S",
                        help="with --residual: the share of the policy's action added to the straight line's "
                             "(default 1: corrections as large as the actions)")
    parser.add_argument("--repeat", type=int, default=1, metavar="K",
                        help="hold each of the policy's actions for K steps of the env (RepeatAction; default 1)")
    parser.add_argument("--normalize", action="store_true",
                        help="normalise observations with running statistics (VecNormalize)")
    args = parser.parse_args()
    try:
        importlib.import_module(LEARNERS[args.learner][0])
    except ImportError:
        raise SystemExit(f"--learner {args.learner} needs {LEARNERS[args.learner][0]}: pip install "
                         f'"hoap-actions[{LEARNERS[args.learner][1]}]"') from None

    if min(args.steps, args.eval_every, args.eval_episodes, args.torch_threads) < 1 or args.eval_first_seed < 0 \
            or not 0.0 < args.gamma < 1.0 or not 0 <= args.demo_steps < args.steps \
            or not 1 <= args.repeat <= args.eval_every or not 0.0 < args.residual_scale <= 1.0:
        print("error: --steps, --eval-every, --eval-episodes and --torch-threads must be >= 1, --eval-first-seed "
              ">= 0, --gamma in (0, 1), --demo-steps in [0, --steps), --repeat in [1, --eval-every] and "
              "--residual-scale in (0, 1]", file=sys.stderr)
        raise SystemExit(2)
    if (args.demo_steps or args.residual) and args.env not in StraightReach.env_ids:
        print(f"error: --demo-steps and --residual use the straight-line reach, which acts in "
              f"{list(StraightReach.env_ids)} only", file=sys.stderr)
        raise SystemExit(2)
    eval_seeds = range(args.eval_first_seed, args.eval_first_seed + args.eval_episodes)
    if args.evaluate is not None:
        try:
            saved = json.loads((args.evaluate / "settings.json").read_text())
            # the env it acted in can be made
            make_env(saved["env"], saved["fields"], *_residual_and_repeat(saved), saved.get("robot", "full")).close()
        except (OSError, ValueError, KeyError, TypeError, HoapActionsError):
            print(f"error: {args.evaluate} holds no policy saved by --save (a readable settings.json naming its env)",
                  file=sys.stderr)
            raise SystemExit(2) from None
        with contextlib.ExitStack() as claims:
            try:
                partial = (claims.enter_context(claimed_file(args.json, args.overwrite, "evaluation")) if args.json
                           else None)
            except HoapActionsError as error:
                print(f"error: {error}", file=sys.stderr)
                raise SystemExit(2) from None
            point = evaluate_saved(args.evaluate, saved, eval_seeds)
            print(json.dumps({key: value for key, value in point.items() if key != "final_distance_m"}))
            if partial is not None:
                partial.write_text(json.dumps({**saved, "eval_seeds": [eval_seeds.start, eval_seeds.stop], **point},
                                              indent=2))
        return
    with contextlib.ExitStack() as claims:
        try:
            if args.fields:
                make_env(args.env, args.fields).close()  # unknown fields fail here, before any training
            partial = (claims.enter_context(claimed_file(args.json, args.overwrite, "learning curve")) if args.json
                       else None)
            folder = claims.enter_context(claimed_directory(
                args.save, args.overwrite, "policy", foreign=_not_a_saved_policy)) if args.save else None
        except HoapActionsError as error:
            print(f"error: {error}", file=sys.stderr)
            raise SystemExit(2) from None
        curve = train(args, eval_seeds, folder)
        if partial is not None:
            partial.write_text(json.dumps({**settings(args), "eval_seeds": [eval_seeds.start, eval_seeds.stop],
                                           "curve": curve}, indent=2))


def settings(args: argparse.Namespace) -> dict:
    """What a run was trained with: written beside its learning curve and its saved policy."""
    return {"env": args.env, "robot": args.robot, "learner": args.learner, "control_mode": CONTROL_MODE,
            "algorithm": "SAC (residual on the straight-line reach)" if args.residual else "SAC + HER",
            "normalize": args.normalize, "fields": args.fields, "gamma": args.gamma, "demo_steps": args.demo_steps,
            "residual": args.residual, "residual_scale": args.residual_scale if args.residual else None,
            "repeat": args.repeat, "seed": args.seed}


def _residual_and_repeat(saved: dict) -> tuple[float, int]:
    """The residual's scale (0: none) and the action repeat a saved policy acted with (older saves: 1 and 1)."""
    residual = (saved.get("residual_scale") or 1.0) if saved["residual"] else 0.0
    return residual, saved.get("repeat", 1)


def _sac(learner: str) -> type:
    """The SAC class of ``learner`` (a key of :data:`LEARNERS`): both take the same settings and files."""
    return importlib.import_module(LEARNERS[learner][0]).SAC


def _share(value: float | None) -> str:
    return "-" if value is None else f"{value:.0%}"


def _not_a_saved_policy(folder: Path) -> list[str]:
    """What a folder written by --save does not hold, which --overwrite must not delete."""
    return sorted(p.name for p in folder.iterdir() if p.name not in SAVED_FILES or not p.is_file())


def evaluate_saved(folder: Path, saved: dict, eval_seeds: range) -> dict:
    """Evaluate a policy saved by ``--save``, its normalisation statistics frozen."""
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    residual, repeat = _residual_and_repeat(saved)
    robot = saved.get("robot", "full")  # older saves: the free-standing robot, with SB3's SAC
    # HER's buffer asks for an env
    venv = DummyVecEnv([lambda: make_env(saved["env"], saved["fields"], residual, repeat, robot)])
    model = _sac(saved.get("learner", "sb3")).load(folder / "policy.zip", env=venv, device="cpu")
    normalize = lambda obs: obs  # noqa: E731  (the identity, replaced when normalising)
    if (folder / "normalize.pkl").is_file():
        stats = VecNormalize.load(str(folder / "normalize.pkl"), venv)
        stats.training = False
        normalize = stats.normalize_obs
    try:
        return evaluate(model, saved["env"], saved["fields"], eval_seeds, normalize, residual, repeat, robot)
    finally:
        venv.close()


def train(args: argparse.Namespace, eval_seeds: range, folder: Path | None) -> list[dict]:
    """Train with an evaluation every ``--eval-every`` steps; the learning curve. The policy is saved in
    ``folder`` (``policy.zip``, and ``normalize.pkl`` with ``--normalize``) when one is given."""
    import torch
    from stable_baselines3 import HerReplayBuffer
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    torch.set_num_threads(args.torch_threads)
    SAC = _sac(args.learner)
    residual = args.residual_scale if args.residual else 0.0
    venv = make_vec_env(make_env, n_envs=1, seed=args.seed,
                        env_kwargs={"env_id": args.env, "fields": args.fields, "residual": residual,
                                    "repeat": args.repeat, "robot": args.robot})
    normalize = lambda obs: obs  # noqa: E731  (the identity, replaced when normalising)
    if args.normalize:
        venv = VecNormalize(venv, norm_obs=True, norm_reward=False)

        def normalize(obs):
            venv.training = False
            return venv.normalize_obs(obs)
    reference = StraightReach(venv) if args.demo_steps else None

    class SACFromDemonstrations(SAC):
        """SAC whose warm-up steps follow the straight-line reference (when given) instead of uniform noise."""

        def _sample_action(self, learning_starts, action_noise=None, n_envs=1):
            if reference is None or self.num_timesteps * args.repeat >= args.demo_steps:
                return super()._sample_action(learning_starts, action_noise, n_envs)
            obs = self._last_original_obs if self._vec_normalize_env is not None else self._last_obs
            action = np.stack([reference({key: value[i] for key, value in obs.items()}) for i in range(n_envs)])
            return action, self.policy.scale_action(action)

    model = SACFromDemonstrations(
                "MultiInputPolicy", venv, replay_buffer_class=None if args.residual else HerReplayBuffer,
                replay_buffer_kwargs=(None if args.residual
                                      else {"n_sampled_goal": 4, "goal_selection_strategy": "future"}),
                learning_starts=max(1000, args.demo_steps // args.repeat), learning_rate=1e-3, gamma=args.gamma,
                tau=0.05, batch_size=256, policy_kwargs={"net_arch": [256, 256]}, seed=args.seed, verbose=0)
    curve, start, learning = [], time.perf_counter(), 0.0
    for _ in range(0, args.steps, args.eval_every):
        began = time.perf_counter()
        model.learn(args.eval_every // args.repeat, reset_num_timesteps=False)  # decisions; the env's steps <= K times
        learning += time.perf_counter() - began
        point = {"steps": int(model.num_timesteps) * args.repeat, "decisions": int(model.num_timesteps),
                 "train_wall_s": time.perf_counter() - start, "learn_wall_s": learning,
                 "training_success_last_100": (float(np.mean(model.ep_success_buffer)) if model.ep_success_buffer
                                               else None),
                 **evaluate(model, args.env, args.fields, eval_seeds, normalize, residual, args.repeat, args.robot)}
        curve.append(point)
        if args.normalize:
            venv.training = True  # the statistics were frozen for the evaluation
        print(f"{point['steps']:6d} steps, {point['train_wall_s'] / 60:5.1f} min: success {point['success_rate']:.0%} "
              f"on {point['episodes']} layouts (median end distance {np.median(point['final_distance_m']) * 100:.1f} "
              "cm; "
              f"training episodes, last 100: {_share(point['training_success_last_100'])}), falls {point['falls']}",
              flush=True)
    if folder is not None:
        model.save(folder / "policy.zip")
        if args.normalize:
            venv.save(str(folder / "normalize.pkl"))
        (folder / "settings.json").write_text(json.dumps({**settings(args),
                                                          "steps": int(model.num_timesteps) * args.repeat}))
    venv.close()
    return curve


if __name__ == "__main__":
    main()
