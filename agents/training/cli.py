"""``pneunet-grasp train``'s command line: the options, then one run (:func:`agents.training.train.train`) or, with
``--seeds N``, a seed study (:func:`agents.training.seeds.run_seeds`); ``--export`` after either. See
:mod:`agents.training.train` for what a run writes.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from agents.training.config import ENV_ID, _count, load_train_config
from agents.training.export import export, export_source
from agents.training.train import _command, latest_checkpoint, train
from pneunet_env.arguments import count, integer, output_dir, output_file, real
from pneunet_env.arguments import seed as seed_type

__all__ = ["add_arguments", "run"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config", required=True,
                        help="rl-zoo3 hyperparameter YAML (configs/train/ppo.yaml), or a shipped config's name (ppo, "
                             "sac); this command's own keys are read from NAME.project.yaml beside it")
    parser.add_argument("--run-dir", type=output_dir, default=None, help="output directory (default runs/<algo>)")
    parser.add_argument("--resume", nargs="?", const="latest", default=None, metavar="CHECKPOINT",
                        help="resume from CHECKPOINT.zip, or (no value) from the newest checkpoint of --run-dir")
    parser.add_argument("--resume-vecnormalize", type=Path, default=None, metavar="PATH",
                        help="with --resume: the normalisation statistics to go on with (.json, or a .pkl: a pickle "
                             "runs code, and is loaded only when named here); default: the JSON beside the checkpoint")
    parser.add_argument("--timesteps", type=real(1, 1e12), default=None, help="override n_timesteps")
    parser.add_argument("--n-envs", type=integer(1, 65536, "--n-envs"), default=None, help="override n_envs")
    parser.add_argument("--seed", type=seed_type, default=None, help="override seed")
    parser.add_argument("--eval-freq", type=real(1, 1e12), default=None, help="override eval_freq (timesteps)")
    parser.add_argument("--n-eval-episodes", type=integer(1, 1_000_000, "--n-eval-episodes"), default=None,
                        help="override n_eval_episodes")
    parser.add_argument("--checkpoint-freq", type=real(1, 1e12), default=None,
                        help="override checkpoint_freq (timesteps)")
    parser.add_argument("--max-minutes", type=real(0, 1e7, above=True), default=None, help="override max_train_minutes")
    parser.add_argument("--vec-env", choices=("batched", "dummy"), default=None, help="override vec_env")
    parser.add_argument("--threads", type=integer(1, 1024, "--threads"), default=None,
                        help="torch threads (override torch_threads; default 1: the batched env's numba threads run "
                             "beside it)")
    parser.add_argument("--seeds", type=integer(1, 1000, "--seeds"), default=None, metavar="N",
                        help="train N seeds (seed, seed+1, ...) in RUN_DIR/seed-K, then score each on held-out objects "
                             "with its untrained start and best-ramp: seeds.json, learning_curves.png; --export then "
                             "exports the median seed's model (agents.training.seeds)")
    parser.add_argument("--jobs", type=integer(1, 1024, "--jobs"), default=1,
                        help="with --seeds: seeds trained at once, one process each")
    parser.add_argument("--objects", type=count, default=400,
                        help="with --seeds: held-out objects each seed's model is scored on (default 400, demo's)")
    parser.add_argument("--export", type=output_file, default=None, metavar="PATH_STEM",
                        help="copy the best model to PATH_STEM.zip (+ _vecnormalize.json, .json), "
                             "e.g. agents/models/ppo_pneunet")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="set an environment config key in env_kwargs (repeatable; VALUE is YAML), e.g. "
                             "--set observe_volume=true")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--force", action="store_true",
                        help="take over the run folder's lock even if the process holding it looks alive (or ran on "
                             "another host): only when you know it is gone (a lock of a dead process on this host is "
                             "taken over without it)")


def run(args: argparse.Namespace) -> int:
    from pneunet_env.extras import require_extra

    for module in ("torch", "stable_baselines3"):  # one line naming the extra, before the config is read
        require_extra("train", module, "rl", "training (stable-baselines3 on torch)")
    try:
        from agents.common.resources import resolve_config

        args.config_given = getattr(args, "config_given", args.config)  # as typed: the run's record shows it
        args.config = str(resolve_config(args.config, "train"))
        hp = load_train_config(args.config)
        for key, value in (("n_timesteps", args.timesteps), ("n_envs", args.n_envs), ("seed", args.seed),
                           ("eval_freq", args.eval_freq), ("n_eval_episodes", args.n_eval_episodes),
                           ("checkpoint_freq", args.checkpoint_freq)):
            if value is not None:
                hp[key] = _count(key, value) if key != "seed" else int(value)
        if args.max_minutes is not None:
            if not args.max_minutes > 0:
                raise ValueError(f"--max-minutes must be > 0, got {args.max_minutes}")
            hp["max_train_minutes"] = float(args.max_minutes)
        if args.vec_env is not None:
            hp["vec_env"] = args.vec_env
        if args.threads is not None:
            hp["torch_threads"] = _count("--threads", args.threads)
        if args.overrides:
            from agents.common.cli import parse_overrides
            from pneunet_env.config import load_config

            env_kwargs = {**(hp.get("env_kwargs") or {}), **parse_overrides(args.overrides)}
            load_config(None, **env_kwargs)  # a bad key or value is named here, before training starts
            hp["env_kwargs"] = env_kwargs
    except ValueError as exc:
        raise SystemExit(f"pneunet-grasp train: {exc}") from None
    run_dir = args.run_dir or Path("runs") / hp["algo"]
    if (named := getattr(args, "resume_vecnormalize", None)) is not None and args.resume is None:
        raise SystemExit(f"pneunet-grasp train: --resume-vecnormalize {named} needs --resume")
    if args.seeds is not None:
        from agents.training.seeds import run_seeds

        return run_seeds(args, hp, run_dir)
    resume = None
    if args.resume is not None:
        resume = latest_checkpoint(run_dir) if args.resume == "latest" else Path(args.resume)
        if resume is None or not resume.is_file():
            raise SystemExit(f"pneunet-grasp train: no checkpoint to resume from ({args.resume} in {run_dir})")
    if named is not None and not named.is_file():
        raise SystemExit(f"pneunet-grasp train: --resume-vecnormalize {named}: no such file")
    print(f"training {hp['algo'].upper()} on {ENV_ID} ({hp['vec_env']} vec env, {hp['n_envs']} envs) for "
          f"{hp['n_timesteps']} timesteps, at most {hp['max_train_minutes']:g} min; seed {hp['seed']}; -> {run_dir}"
          + (f"; resuming from {resume}" if resume else ""))
    record = train(hp, run_dir, resume, progress=not args.no_progress, config_path=str(args.config),
                   command=_command(args, run_dir), force=getattr(args, "force", False), resume_vecnormalize=named)
    inv = record["invocations"][-1]
    print(f"{inv['end_timesteps']} timesteps ({inv['end_timesteps'] - inv['start_timesteps']} this run) in "
          f"{inv['wall_s']:.0f} s; best evaluation: {record['best_eval']}")
    if args.export is not None:
        path = export(run_dir, args.export, record)
        print(f"exported {export_source(run_dir)} to {path}")
    return 0
