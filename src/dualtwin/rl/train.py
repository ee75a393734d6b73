"""PPO training (Stable-Baselines3) on any registered dualtwin env, with a run folder users recognise (zoo layout).

Run folder::

    OUT/config.yaml                resolved training config (the YAML given, plus defaults and overrides)
    OUT/run.json                   env id, seed, versions, I/O contract, status, timings, evaluation timeline
    OUT/model.zip                  final policy          OUT/vecnormalize.json      its observation statistics
    OUT/best_model.zip             best evaluated policy OUT/best_vecnormalize.json its statistics
    OUT/evaluations.npz            EvalCallback log      OUT/dr_ranges.json         randomisation ranges, if any
    OUT/aligned_knobs.json         the aligned knob values trained with, if any (run.json: their file and hash)
    OUT/checkpoints/rl_model_<N>_steps.zip (+ rl_model_vecnormalize_<N>_steps.json)

Nothing in a run folder is unpickled when it is read back (:mod:`dualtwin.rl.runfiles`): statistics are JSON,
and the model zips load with every pickled entry rebuilt from ``run.json``. Runs written before that
(``vecnormalize.pkl``) load only with ``trust_pickles=True``.
    OUT/tb/                        TensorBoard           OUT/monitor/               Monitor CSVs per env

``resume=True`` continues an interrupted run from its newest checkpoint (the same env, seed and config).
``aligned=`` trains in the aligned twin: the fitted knobs (``align``'s ``knobs.json``) define the training and
evaluation envs' physics, from nominal at every reset, and go into the run's ``env_kwargs``, so whatever
rebuilds the source env later (transfer, export checks) gets the aligned twin back.
"""

from __future__ import annotations

import contextlib
import re
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from dualtwin.artifacts import package_versions, write_json, write_text
from dualtwin.errors import DualtwinError
from dualtwin.rl.curves import evaluation_line
from dualtwin.rl.ppo_config import PPOConfig, activation, learning_rate_schedule, load_config
from dualtwin.rl.runfiles import load_model, load_normalization, save_normalization, stats_path

if TYPE_CHECKING:
    import gymnasium as gym
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import EvalCallback
    from stable_baselines3.common.vec_env import VecNormalize

RUN_VERSION = 1
_CHECKPOINT = re.compile(r"^rl_model_(\d+)_steps\.zip$")


def _read_json(path: Path) -> dict[str, Any]:
    from dualtwin.artifacts import read_json_object

    return read_json_object(path, what="run record")  # names file, line and column; refuses a non-object


def _latest_checkpoint(out: Path, final_steps: int | None) -> tuple[Path, Path, int] | None:
    """The newest (model, vecnormalize, steps) to resume from: a checkpoint, or the final model if newer."""
    found: list[tuple[int, Path, Path]] = []
    folder = out / "checkpoints"
    if folder.is_dir():
        for path in folder.iterdir():
            match = _CHECKPOINT.match(path.name)
            if match:
                steps = int(match.group(1))
                stats = stats_path(folder, f"rl_model_vecnormalize_{steps}_steps") \
                    or folder / f"rl_model_vecnormalize_{steps}_steps.json"
                found.append((steps, path, stats))
    if final_steps is not None and (out / "model.zip").is_file():
        found.append((final_steps, out / "model.zip", stats_path(out, "vecnormalize") or out / "vecnormalize.json"))
    if not found:
        return None
    steps, model, stats = max(found, key=lambda item: item[0])
    return model, stats, steps


def _check_task_options(env_id: str, env_kwargs: dict[str, Any], origin: str) -> None:
    """The config's ``task_kwargs`` against the task this env id runs, before the run folder is made (the envs
    are built after it; ``pole_joint: null`` killed the process there with SIGSEGV, rl.env.check_task_kwargs)."""
    from dualtwin.registration import ENV_IDS
    from dualtwin.rl.env import TASKS, check_task_kwargs

    task = env_kwargs.get("task", ENV_IDS.get(env_id, {}).get("task", "cartpole_balance"))
    if task in TASKS:  # an unknown task is named when the env is built
        check_task_kwargs(task, env_kwargs.get("task_kwargs"), f"{origin}env_kwargs.task_kwargs (task {task!r})")


def _make_env_fn(env_id: str, env_kwargs: dict[str, Any], dr: dict[str, Any] | None
                 ) -> Callable[[], gym.Env[Any, Any]]:
    def build() -> gym.Env[Any, Any]:
        from dualtwin.rl import make_env
        from dualtwin.rl.randomize import DomainRandomization

        env = make_env(env_id, **env_kwargs)
        return DomainRandomization(env, {"knobs": dr}) if dr else env

    return build


def train(env_id: str, config_path: Path | str | Mapping[str, Any] | PPOConfig | None, out_dir: Path | str, *,
          seed: int = 0, total_timesteps: int | None = None, resume: bool = False,
          dr_ranges: Path | str | Mapping[str, Any] | None = None, progress_bar: bool = True,
          verbose: int = 0, shadow_fraction: float = 0.0,
          aligned: Path | str | Mapping[str, Any] | None = None, init_from: Path | str | None = None,
          trust_pickles: bool | None = None, report: Callable[[str], None] | None = None) -> Path:
    """Train PPO on ``env_id`` into ``out_dir`` and return it (see the module docstring for its contents).

    Args:
        env_id: a registered dualtwin env id.
        config_path: PPO config YAML (``None``: the bundled ``ppo_cartpole.yaml``), a dict or a :class:`PPOConfig`.
        out_dir: run folder; must be empty unless ``resume``.
        seed: seeds PyTorch, the envs (``seed + i``) and the evaluation env (``seed + 10_000``).
        total_timesteps: overrides the config's ``n_timesteps``.
        resume: continue the interrupted run in ``out_dir`` from its newest checkpoint.
        dr_ranges: domain randomisation ranges (file or dict) for the training envs; evaluation stays nominal.
        progress_bar: show SB3's progress bar.
        verbose: SB3 verbosity.
        shadow_fraction: share of training episodes mirrored into a shadow Webots twin, whose divergence goes
            to TensorBoard under ``shadow/`` (:class:`dualtwin.rl.shadow.ShadowCallback`; needs
            ``vec_env: dummy``).
        aligned: aligned knob values (``knobs.json`` from ``dualtwin align --target <this env's twin>``, or a
            ``{name: value}`` dict) applied to every training and evaluation env; domain randomisation, if
            any, draws on top of them.
        init_from: fine-tune: start from this run's best policy (``best_model.zip``, else ``model.zip``) and its
            VecNormalize statistics, which keep adapting; the network is that run's, the PPO settings (learning
            rate, rollout, epochs...) this config's. The run must be on the same env id. Typical use: a policy trained in the nominal twin, fine-tuned in the
            aligned twin (``aligned=``) or with calibrated domain randomisation.
        trust_pickles: allow unpickling an old run's ``vecnormalize.pkl`` (resume or ``init_from``); pickles
            can run code, so only for files the user trusts.
        report: called with a few set-up lines (loading, building the environments, the steps to train)
            and then one line per evaluation (steps, mean reward, mean length, wall time); the CLI prints
            them to stderr.
    """
    from dualtwin.rl import check_env_id
    from dualtwin.rl.randomize import load_ranges

    check_env_id(env_id)
    config = load_config(config_path)
    _check_task_options(env_id, config.env_kwargs,
                        f"{config_path}: " if isinstance(config_path, str | Path) else "")
    aligned_record = _aligned_record(env_id, config, aligned) if aligned is not None else None
    init_record = _init_record(env_id, init_from) if init_from is not None else None
    if init_record is not None and (init_record["vecnormalize"] is None) != (config.normalize_config is None):
        raise DualtwinError(f"{init_from}: its observation normalisation does not match this config's "
                            "'normalize' setting; a fine-tuned policy must see the inputs it was trained on")
    if shadow_fraction and config.vec_env != "dummy":
        raise DualtwinError("shadow_fraction needs vec_env: dummy in the config (the shadow mirrors in-process "
                            "envs; the bundled configs use subproc)")
    if config.stop_reward is not None and config.eval_freq == 0:  # before the run folder exists (issue 14)
        raise DualtwinError("stop_reward needs evaluation (eval_freq > 0)")
    total = int(total_timesteps if total_timesteps is not None else config.n_timesteps)
    if total <= 0:
        raise DualtwinError(f"total_timesteps must be positive, got {total}")
    out = Path(out_dir)
    ranges = load_ranges(dr_ranges) if dr_ranges else None
    if ranges is not None:
        _check_ranges(env_id, config, ranges, str(dr_ranges) if isinstance(dr_ranges, str | Path) else "dr ranges")
    dr = {k: v.model_dump(exclude_none=True) for k, v in ranges.items()} if ranges is not None else None
    config_record = config.model_dump(mode="json")
    run_path = out / "run.json"

    previous: dict[str, Any] | None = None
    restarting = False
    if resume and run_path.is_file():
        previous = _read_json(run_path)
        if previous.get("status") == STARTING:
            # it failed before training (say, building its envs): nothing to resume, so it starts afresh
            previous, restarting = None, True
    if previous is not None:
        differ = [name for name, old, new in (("env id", previous.get("env_id"), env_id),
                                               ("seed", previous.get("seed"), seed),
                                               ("config", _without_steps(previous.get("config")),
                                                _without_steps(config_record)),
                                               ("domain randomisation", previous.get("dr_ranges"), dr),
                                               ("aligned knobs", _values(previous.get("aligned")),
                                                _values(aligned_record)),
                                               ("initial policy", (previous.get("init_from") or {}).get("sha256"),
                                                (init_record or {}).get("sha256")))
                  if old != new]
        if differ:
            raise DualtwinError(f"{run_path}: cannot resume: {', '.join(differ)} differ from the interrupted run")
        if previous.get("status") == "complete" and previous.get("num_timesteps", 0) >= total:
            return out
    elif not restarting and out.exists() and any(out.iterdir()):
        raise DualtwinError(f"{out}: output folder is not empty; use resume to continue a run, "
                            "or choose another folder")
    final_steps = previous.get("num_timesteps") if previous and previous.get("status") == "complete" else None
    start_from = _latest_checkpoint(out, final_steps) if previous else None
    config_record["n_timesteps"] = total
    out.mkdir(parents=True, exist_ok=True)
    if previous is None:
        # the run's record comes first, so a run that fails before training still leaves a folder that is
        # recognisably this command's and that --resume accepts (issue 14: a failed run never locks its folder)
        write_json(run_path, {"env_id": env_id, "seed": seed, "status": STARTING})
    write_text(out / "config.yaml", yaml.safe_dump(config_record, sort_keys=False))
    if dr:
        write_json(out / "dr_ranges.json", {"knobs": dr})
    if aligned_record is not None:
        write_json(out / "aligned_knobs.json", aligned_record)
    trainer = _Trainer(env_id, config, out, seed, total, dr, previous, start_from, progress_bar, verbose)
    trainer.shadow_fraction = float(shadow_fraction)
    trainer.aligned = aligned_record
    trainer.init_from = init_record
    trainer.trust_pickles = trust_pickles
    trainer.report = report
    if aligned_record is not None:
        kwargs = dict(config.env_kwargs)
        trainer.env_kwargs = {**kwargs, "knobs": {**dict(kwargs.get("knobs") or {}), **aligned_record["values"]}}
    return trainer.run()


#: ``run.json``'s status from the moment a run's folder is made until its trainer first records it.
STARTING = "starting"


def _init_record(env_id: str, run: Path | str) -> dict[str, Any]:
    """The policy a fine-tuning run starts from: its files and hash, checked against ``env_id``."""
    from dualtwin.artifacts import sha256_file

    folder = Path(run)
    if not (folder / "run.json").is_file():
        raise DualtwinError(f"{folder}: not a training run (no run.json) to start from")
    record = _read_json(folder / "run.json")
    if record.get("env_id") != env_id:
        raise DualtwinError(f"{folder}: trained on {record.get('env_id')!r}; it can only be fine-tuned on that env, "
                            f"not {env_id!r}")
    for prefix in ("best_", ""):
        model, stats = folder / f"{prefix}model.zip", stats_path(folder, f"{prefix}vecnormalize")
        if model.is_file():
            return {"run": str(folder.resolve()), "model": str(model.resolve()), "sha256": sha256_file(model),
                    "vecnormalize": str(stats.resolve()) if stats is not None else None}
    raise DualtwinError(f"{folder}: no best_model.zip or model.zip to start from")


def _values(record: Any) -> Any:
    return record.get("values") if isinstance(record, dict) else None


def _aligned_record(env_id: str, config: PPOConfig, aligned: Path | str | Mapping[str, Any]) -> dict[str, Any]:
    """Read the aligned knobs and check, before any training, that they belong to this env's twin."""
    from dualtwin.rl import make_env
    from dualtwin.rl.randomize import check_aligned_twin, check_knob_names, read_aligned

    record = read_aligned(aligned)
    env: Any = make_env(env_id, **{k: v for k, v in config.env_kwargs.items() if k != "knobs"})
    try:
        twin = env.unwrapped.twin_name
        check_aligned_twin(record, twin, env_id)
        known = env.unwrapped.twin.knobs()
    finally:
        env.close()
    check_knob_names(list(record["values"]), known, f"{record.get('file') or 'aligned knobs'} ({env_id})")
    for name, value in record["values"].items():
        knob = known[name]
        if not knob.lower <= value <= knob.upper:
            raise DualtwinError(f"{record.get('file') or 'aligned knobs'}: {name} = {value:g} is outside the "
                                f"knob's bounds [{knob.lower:g}, {knob.upper:g}]")
    return record


def _check_ranges(env_id: str, config: PPOConfig, ranges: Mapping[str, Any], origin: str) -> None:
    """The DR ranges against this env's twin, before any training: in the environment workers the same check
    (DomainRandomization) fails inside a subprocess, after the run folder exists, as a worker's traceback."""
    from dualtwin.rl import make_env
    from dualtwin.rl.randomize import check_ranges

    env: Any = make_env(env_id, **{k: v for k, v in config.env_kwargs.items() if k != "knobs"})
    try:
        known = env.unwrapped.twin.knobs()
    finally:
        env.close()
    check_ranges(ranges, known, f"{origin} ({env_id})")


def _without_steps(config: Any) -> Any:
    if not isinstance(config, dict):
        return config
    return {k: v for k, v in config.items() if k != "n_timesteps"}


class _Trainer:
    """One training session (fresh or resumed); keeps :func:`train` readable."""

    def __init__(self, env_id: str, config: PPOConfig, out: Path, seed: int, total: int,
                 dr: dict[str, Any] | None, previous: dict[str, Any] | None,
                 start_from: tuple[Path, Path, int] | None, progress_bar: bool, verbose: int) -> None:
        self.env_id, self.config, self.out, self.seed, self.total = env_id, config, out, seed, total
        self.dr, self.previous, self.start_from = dr, previous, start_from
        self.progress_bar, self.verbose = progress_bar, verbose
        self.shadow_fraction = 0.0
        self.aligned: dict[str, Any] | None = None
        self.init_from: dict[str, Any] | None = None
        self.trust_pickles: bool | None = None
        self.report: Callable[[str], None] | None = None
        self.env_kwargs: dict[str, Any] = dict(config.env_kwargs)
        self.model: PPO | None = None
        self.contract: dict[str, Any] = {}
        self.session_start = time.perf_counter()
        self.start_steps = 0
        self.max_episode_steps: int | None = None
        self.timeline: list[dict[str, float]] = list((previous or {}).get("evaluations", []))
        if start_from is not None:
            self.timeline = [e for e in self.timeline if e["timesteps"] <= start_from[2]]
        self.prior_seconds = float((previous or {}).get("timings", {}).get("train_seconds", 0.0))
        if start_from is None:
            self.timeline, self.prior_seconds = [], 0.0

    def _record(self, status: str) -> None:
        """Rewrite run.json (at the start, after every evaluation and at the end), so it always shows progress."""
        model, contract = self.model, self.contract
        elapsed = time.perf_counter() - self.session_start
        session_steps = int(model.num_timesteps) - self.start_steps if model is not None else 0
        threshold = self.config.stop_reward
        reached = next((e for e in self.timeline if threshold is not None and e["mean_reward"] >= threshold), None)
        record = {
            "run_version": RUN_VERSION,
            "status": status,
            "env_id": self.env_id,
            "env_kwargs": self.env_kwargs,
            "max_episode_steps": self.max_episode_steps,
            "seed": self.seed,
            "algo": "ppo",
            "num_timesteps": int(model.num_timesteps) if model is not None else 0,
            "total_timesteps": self.total,
            "config": self.config.model_dump(mode="json"),
            "dr_ranges": self.dr,
            "aligned": self.aligned,
            "init_from": self.init_from,
            "shadow_fraction": self.shadow_fraction,
            "io": contract,
            "versions": package_versions(),
            "timings": {
                "train_seconds": round(self.prior_seconds + elapsed, 3),
                "session_seconds": round(elapsed, 3),
                "session_steps": session_steps,
                "session_steps_per_second": round(session_steps / elapsed, 1) if elapsed > 0 else None,
                "threshold_reached": reached,
            },
            "resumed_from_steps": self.start_from[2] if self.start_from else None,
            "best_mean_reward": max((e["mean_reward"] for e in self.timeline), default=None),
            "evaluations": self.timeline,
        }
        write_json(self.out / "run.json", record)

    def _say(self, line: str) -> None:
        if self.report is not None:
            self.report(line)

    def run(self) -> Path:
        # The first seconds (importing PyTorch and SB3, building every environment) would otherwise be silent
        # until SB3's progress bar appears.
        self._say("loading PyTorch and Stable-Baselines3")
        import torch
        from stable_baselines3 import PPO
        from stable_baselines3.common.callbacks import (
            BaseCallback,
            CallbackList,
            EvalCallback,
            StopTrainingOnRewardThreshold,
        )
        from stable_baselines3.common.env_util import make_vec_env
        from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize

        cfg, out = self.config, self.out
        threads = torch.get_num_threads()
        torch.set_num_threads(cfg.torch_threads)
        norm = cfg.normalize_config
        vec_cls = SubprocVecEnv if cfg.vec_env == "subproc" else DummyVecEnv
        self._say(f"building {cfg.n_envs} training and {min(cfg.eval_episodes, 8)} evaluation environments of "
                  f"{self.env_id}")
        venv: Any = make_vec_env(_make_env_fn(self.env_id, self.env_kwargs, self.dr), n_envs=cfg.n_envs,
                                 seed=self.seed, monitor_dir=str(out / "monitor"), vec_env_cls=vec_cls,
                                 monitor_kwargs={"override_existing": self.start_from is None})
        n_eval = min(cfg.eval_episodes, 8)
        eval_env: Any = make_vec_env(_make_env_fn(self.env_id, self.env_kwargs, None), n_envs=n_eval,
                                     seed=self.seed + 10_000)
        contract = self.contract = eval_env.envs[0].unwrapped.io_contract()
        self.max_episode_steps = eval_env.envs[0].spec.max_episode_steps if eval_env.envs[0].spec else None
        # A checkpoint to resume from, else (fine-tuning) the initial policy; either way its statistics go on.
        load: tuple[str, str | None] | None = (str(self.start_from[0]), str(self.start_from[1])) \
            if self.start_from is not None else \
            (self.init_from["model"], self.init_from["vecnormalize"]) if self.init_from is not None else None
        if norm is not None:
            if load is not None and load[1] is not None:
                venv = load_normalization(Path(load[1]), venv, trust_pickles=self.trust_pickles)
                venv.training = True
            else:
                venv = VecNormalize(venv, norm_obs=norm.norm_obs, norm_reward=norm.norm_reward,
                                    clip_obs=norm.clip_obs, clip_reward=norm.clip_reward, gamma=cfg.gamma)
            # Evaluation uses the training statistics (EvalCallback syncs them) and raw rewards.
            eval_env = VecNormalize(eval_env, training=False, norm_obs=norm.norm_obs, norm_reward=False,
                                    clip_obs=norm.clip_obs)

        if load is not None:
            # Fine-tuning keeps the network but takes this config's PPO settings (a lower learning rate, say);
            # SB3 rebuilds the rollout buffer and schedules from them.
            tuning = {} if self.start_from is not None else {
                "learning_rate": learning_rate_schedule(cfg.learning_rate), "n_steps": cfg.n_steps,
                "batch_size": cfg.batch_size, "n_epochs": cfg.n_epochs, "gamma": cfg.gamma,
                "gae_lambda": cfg.gae_lambda, "clip_range": cfg.clip_range, "ent_coef": cfg.ent_coef,
                "vf_coef": cfg.vf_coef, "max_grad_norm": cfg.max_grad_norm, "sde_sample_freq": cfg.sde_sample_freq}
            # Every pickled entry of the zip is rebuilt from the run record it came with (nothing is unpickled).
            source = self.previous if self.start_from is not None else \
                _read_json(Path(self.init_from["run"]) / "run.json") if self.init_from is not None else {}
            model = load_model(Path(load[0]), source or {}, env=venv, tensorboard_log=str(out / "tb"),
                               custom_objects=tuning, trust_pickles=self.trust_pickles)
            if self.start_from is None:
                # Fine-tuning is a new run: its own seed and step count.
                model.set_random_seed(self.seed)
                model.num_timesteps = 0
        else:
            pk = cfg.policy_kwargs
            policy_kwargs: dict[str, Any] = {"net_arch": dict(pk.net_arch), "activation_fn": activation(pk.activation_fn),
                                             "ortho_init": pk.ortho_init}
            if contract["action"]["type"] == "box":
                policy_kwargs["log_std_init"] = pk.log_std_init
            model = PPO(cfg.policy, venv, learning_rate=learning_rate_schedule(cfg.learning_rate), n_steps=cfg.n_steps,
                        batch_size=cfg.batch_size, n_epochs=cfg.n_epochs, gamma=cfg.gamma,
                        gae_lambda=cfg.gae_lambda, clip_range=cfg.clip_range, ent_coef=cfg.ent_coef,
                        vf_coef=cfg.vf_coef, max_grad_norm=cfg.max_grad_norm, policy_kwargs=policy_kwargs,
                        use_sde=cfg.use_sde and contract["action"]["type"] == "box",
                        sde_sample_freq=cfg.sde_sample_freq,
                        tensorboard_log=str(out / "tb"), seed=self.seed, device="cpu", verbose=self.verbose)

        self.model = model
        self.session_start = session_start = time.perf_counter()
        trainer = self

        class _TimedEval(EvalCallback):
            """EvalCallback that also appends (steps, mean reward, wall time) to the run's timeline.

            Recorded here rather than in ``callback_after_eval``: SB3 skips that one when the evaluation that
            crosses ``stop_reward`` ends training, which is exactly the evaluation the timeline must show.
            """

            def _on_step(self) -> bool:
                count = len(self.evaluations_results)
                keep_going = super()._on_step()
                if len(self.evaluations_results) > count:
                    rewards = np.asarray(self.evaluations_results[-1], dtype=float)
                    lengths = np.asarray(self.evaluations_length[-1], dtype=float)
                    trainer.timeline.append({
                        "timesteps": int(self.num_timesteps), "mean_reward": float(rewards.mean()),
                        "std_reward": float(rewards.std()), "mean_length": float(lengths.mean()),
                        "wall_seconds": round(trainer.prior_seconds + time.perf_counter() - session_start, 3)})
                    trainer._record("running")
                    if trainer.report is not None:
                        trainer.report(evaluation_line(trainer.timeline[-1], trainer.total))
                return keep_going

        class _WallClockLimit(BaseCallback):
            """Stops training once this session has run ``seconds`` (a budget, as in the benchmark)."""

            def __init__(self, seconds: float) -> None:
                super().__init__()
                self.deadline = time.perf_counter() + seconds

            def _on_step(self) -> bool:
                return time.perf_counter() < self.deadline

        class _Checkpoint(BaseCallback):
            """SB3's CheckpointCallback, with the statistics as JSON (its own writes them as a pickle)."""

            def __init__(self, every: int) -> None:
                super().__init__()
                self.every = every

            def _on_step(self) -> bool:
                if self.n_calls % self.every == 0:
                    trainer._emergency_checkpoint(model, force=True)
                return True

        class _RollingLengthStop(BaseCallback):
            """Stops once SB3's window of the last 100 training episodes is full and its mean length >= ``goal``."""

            def __init__(self, goal: float) -> None:
                super().__init__()
                self.goal = goal

            def _on_step(self) -> bool:
                window = self.model.ep_info_buffer
                if window is None or len(window) < (window.maxlen or 0):
                    return True
                return float(np.mean([info["l"] for info in window])) < self.goal

        class _SaveBestStats(BaseCallback):
            def _on_step(self) -> bool:
                stats = self.model.get_vec_normalize_env()
                if stats is not None:
                    save_normalization(stats, out / "best_vecnormalize.json")
                return True

        callbacks: list[BaseCallback] = []
        if cfg.eval_freq:
            on_best: list[BaseCallback] = [_SaveBestStats()]
            if cfg.stop_reward is not None:
                on_best.append(StopTrainingOnRewardThreshold(cfg.stop_reward, verbose=self.verbose))
            evaluation = _TimedEval(eval_env, callback_on_new_best=CallbackList(on_best),
                                    n_eval_episodes=cfg.eval_episodes, eval_freq=max(cfg.eval_freq // cfg.n_envs, 1),
                                    log_path=str(out), best_model_save_path=str(out), deterministic=True,
                                    verbose=self.verbose)
            self._restore_evaluations(evaluation)
            callbacks.append(evaluation)
        if cfg.checkpoint_freq:
            # After evaluation, so a checkpoint at step N comes with the evaluation at step N.
            callbacks.append(_Checkpoint(max(cfg.checkpoint_freq // cfg.n_envs, 1)))
        if cfg.max_wall_seconds is not None:
            callbacks.append(_WallClockLimit(cfg.max_wall_seconds))
        if cfg.stop_episode_length is not None:
            callbacks.append(_RollingLengthStop(cfg.stop_episode_length))
        if self.shadow_fraction > 0:
            from dualtwin.rl.shadow import ShadowCallback

            callbacks.append(ShadowCallback(self.shadow_fraction, seed=self.seed))
        if cfg.stop_reward is not None and cfg.eval_freq == 0:
            raise DualtwinError("stop_reward needs evaluation (eval_freq > 0)")

        start_steps = self.start_steps = int(model.num_timesteps)
        self._record("running")
        evaluations = f", evaluating every {cfg.eval_freq} steps" if cfg.eval_freq else ""
        self._say(f"training: steps {start_steps} to {self.total}{evaluations}")
        try:
            model.learn(total_timesteps=max(self.total - start_steps, 0), callback=CallbackList(callbacks),
                        progress_bar=self.progress_bar, reset_num_timesteps=self.start_from is None,
                        tb_log_name="PPO")
        except BaseException:
            # Keep what was learned: the next resume starts here rather than at the last periodic checkpoint.
            self._emergency_checkpoint(model)
            self._record("interrupted")
            with contextlib.suppress(Exception):  # the interruption is what the user must see
                self._curve()
            raise
        finally:
            venv.close()
            eval_env.close()
            torch.set_num_threads(threads)
        model.save(str(out / "model.zip"))
        stats = model.get_vec_normalize_env()
        if stats is not None:
            save_normalization(stats, out / "vecnormalize.json")
        self._record("complete")
        self._curve()
        return out

    def _curve(self) -> None:
        """learning_curve.csv/png from the Monitor CSVs (training episodes, not the evaluations)."""
        from dualtwin.rl.curves import write_learning_curve

        write_learning_curve(self.out, f"{self.env_id}, seed {self.seed}: training episodes")

    def _emergency_checkpoint(self, model: PPO, force: bool = False) -> None:
        if not self.config.checkpoint_freq and not force:
            return
        folder = self.out / "checkpoints"
        folder.mkdir(parents=True, exist_ok=True)
        steps = int(model.num_timesteps)
        # Statistics first: a checkpoint counts (resume looks for the zip) only once both files are there.
        stats: VecNormalize | None = model.get_vec_normalize_env()
        if stats is not None:
            save_normalization(stats, folder / f"rl_model_vecnormalize_{steps}_steps.json")
        model.save(str(folder / f"rl_model_{steps}_steps.zip"))

    def _restore_evaluations(self, evaluation: EvalCallback) -> None:
        """On resume, carry the evaluation history (evaluations.npz, best reward) up to the checkpoint."""
        path = self.out / "evaluations.npz"
        if self.start_from is None or not path.is_file():
            return
        with np.load(path) as data:
            keep = data["timesteps"] <= self.start_from[2]
            evaluation.evaluations_timesteps = [int(t) for t in data["timesteps"][keep]]
            evaluation.evaluations_results = [list(r) for r in data["results"][keep]]
            evaluation.evaluations_length = [list(r) for r in data["ep_lengths"][keep]]
        if evaluation.evaluations_results:
            evaluation.best_mean_reward = float(max(np.mean(r) for r in evaluation.evaluations_results))
