"""Ecosystem conventions a Gymnasium / Stable-Baselines3 user relies on, over every registered id.

test_env.py already pins Gymnasium's ``check_env``, same-seed determinism and ``make_vec`` sync shapes;
test_vector_env.py the batched vector env's bit-identity on observations, rewards and flags; test_train.py the
run folder's file names. This module pins the rest: exact step types, metadata, ``close()`` twice, the
registered time limits, spec round trips, SB3's own ``check_env``, vector-env infos and ``reset_mask``, and that
a run folder is what plain SB3 reads (``PPO.load``, ``evaluations.npz``, Monitor CSVs, the saved config).
Webots-twin envs take one or two steps each.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.envs.registration import EnvSpec
from gymnasium.utils.env_checker import data_equivalence
from tests.support.rl_runs import ALL_IDS, TINY, can_render, env_param

import dualtwin.rl as rl
from dualtwin.errors import DualtwinError
from dualtwin.registration import DEFAULT_MAX_EPISODE_STEPS, MAX_EPISODE_STEPS, VECTOR_ENV_IDS
from dualtwin.rl.vector_env import TwinVectorEnv

CONTINUOUS = "dualtwin/CartPole-MuJoCo-Continuous-v0"


# ------------------------------------------------------------------ single envs, every registered id
@pytest.mark.parametrize("env_id", ALL_IDS)
def test_reset_and_step_return_gymnasium_types(env_id: str) -> None:
    """Python ``float`` reward and ``bool`` flags (not NumPy scalars), arrays of the space's dtype, dict infos,
    and ``np_random`` seeded by ``reset(seed=)`` through ``super().reset``."""
    env = gym.make(env_id)
    obs, info = env.reset(seed=3)
    assert env.unwrapped.np_random_seed == 3
    assert isinstance(obs, np.ndarray) and obs.dtype == env.observation_space.dtype and isinstance(info, dict)
    env.action_space.seed(3)
    out = env.step(env.action_space.sample())
    assert len(out) == 5
    obs, reward, terminated, truncated, info = out
    assert isinstance(obs, np.ndarray) and obs.dtype == env.observation_space.dtype
    assert obs.shape == env.observation_space.shape
    assert type(reward) is float and type(terminated) is bool and type(truncated) is bool
    assert isinstance(info, dict)
    env.close()


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_metadata_declares_render_modes_and_the_control_rate(env_id: str) -> None:
    env = gym.make(env_id)
    unwrapped = env.unwrapped
    for metadata in (env.metadata, type(unwrapped).metadata):
        assert isinstance(metadata["render_modes"], list) and isinstance(metadata["render_fps"], int)
    # Gymnasium's MuJoCo envs: render_fps = round(1 / dt); a video plays at the simulation's rate.
    assert env.metadata["render_fps"] == round(1.0 / unwrapped.control_period)
    assert set(env.metadata["render_modes"]) <= {"rgb_array"}
    env.close()


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_close_twice_is_harmless(env_id: str) -> None:
    env = gym.make(env_id)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    env.close()
    env.close()


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_gym_make_applies_the_registered_time_limit(env_id: str) -> None:
    env = gym.make(env_id)
    cap = MAX_EPISODE_STEPS.get(env_id, DEFAULT_MAX_EPISODE_STEPS)
    assert env.spec is not None and env.spec.max_episode_steps == cap
    assert isinstance(env, gym.wrappers.TimeLimit) and env._max_episode_steps == cap
    env.close()
    # The cap truncates (not terminates), and a shorter one given to gym.make is the one applied.
    env = gym.make(env_id, max_episode_steps=2)
    env.reset(seed=0)
    zero = np.zeros(env.action_space.shape, dtype=env.action_space.dtype) if env.action_space.shape else 0
    flags = [env.step(zero)[2:4] for _ in range(2)]
    if not any(terminated for terminated, _ in flags):
        assert flags == [(False, False), (False, True)]
    env.close()


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_spec_round_trips_through_make_and_json(env_id: str) -> None:
    """``gym.make(env.spec)`` and ``EnvSpec.from_json(spec.to_json())`` rebuild the same env, arguments
    included (zoo and Gymnasium's own tests rebuild envs this way)."""
    env = gym.make(env_id, max_episode_steps=7, control_period=0.016)
    spec = env.spec
    assert spec is not None and spec.kwargs["control_period"] == 0.016
    for again in (gym.make(spec), gym.make(EnvSpec.from_json(spec.to_json()))):
        assert again.spec == spec and again.unwrapped.control_period == 0.016
        assert again.spec is not None and again.spec.max_episode_steps == 7
        assert again.observation_space == env.observation_space and again.action_space == env.action_space
        again.close()
    env.close()


def test_spec_round_trip_keeps_task_options_and_knobs() -> None:
    env = gym.make("dualtwin/CartPole-MuJoCo-v0", task_kwargs={"x_limit": 1.0}, knobs={"body.pole.mass": 0.3})
    again = gym.make(EnvSpec.from_json(env.spec.to_json()))  # type: ignore[union-attr]
    assert again.unwrapped.task.x_limit == 1.0 and again.unwrapped.base_knobs == {"body.pole.mass": 0.3}
    assert data_equivalence(env.reset(seed=4), again.reset(seed=4), exact=True)
    env.close()
    again.close()


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_stable_baselines3_check_env_passes(env_id: str) -> None:
    from stable_baselines3.common.env_checker import check_env

    env = gym.make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # SB3's checker warns about what would silently hurt training
        check_env(env.unwrapped, warn=True, skip_render_check=True)
    env.close()


@pytest.mark.parametrize("own_seed", [None, 11])
def test_domain_randomization_passes_check_env_and_reseeds_at_every_seeded_reset(own_seed: int | None) -> None:
    """Gymnasium's reset contract through the DR wrapper: ``reset(seed=s)`` twice gives the same draw and the
    same episode (only the first seeded reset used to seed the draws)."""
    from gymnasium.utils.env_checker import check_env

    from dualtwin.rl.randomize import DomainRandomization

    ranges = {"knobs": {"body.pole.mass": {"low": 0.15, "high": 0.35}}}
    env = DomainRandomization(gym.make("dualtwin/CartPole-MuJoCo-v0"), ranges, seed=own_seed)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*Box observation space (minimum|maximum) value is")
        warnings.filterwarnings("ignore", message=".*is different from the unwrapped version")  # on purpose
        check_env(env)
    runs = []
    for _ in range(2):
        obs, info = env.reset(seed=5)
        runs.append((info["dr"], obs, [env.step(1)[0] for _ in range(5)], env.reset()[1]["dr"]))
    assert data_equivalence(runs[0], runs[1], exact=True)
    assert runs[0][0] != runs[0][3]  # unseeded resets still draw afresh
    env.close()


def test_knob_wrappers_are_recorded_in_the_spec(tmp_path: Path) -> None:
    """``gym.make(env.spec)`` rebuilds the wrapper stack (Gymnasium's wrappers record their arguments)."""
    from dualtwin.rl.randomize import DomainRandomization, FixedKnobs

    ranges = tmp_path / "dr_ranges.json"
    ranges.write_text(json.dumps({"knobs": {"body.pole.mass": {"low": 0.15, "high": 0.35}}}))
    base = gym.make("dualtwin/CartPole-MuJoCo-v0")
    env = DomainRandomization(FixedKnobs(base, {"joint.pole_hinge.damping": 0.01}), ranges)
    spec = env.spec
    assert spec is not None and [w.name for w in spec.additional_wrappers] == ["FixedKnobs", "DomainRandomization"]
    again = gym.make(spec)
    assert isinstance(again, DomainRandomization) and isinstance(again.env, FixedKnobs)
    assert data_equivalence(env.reset(seed=2), again.reset(seed=2), exact=True)
    assert again.reset(seed=2)[1]["knobs"] == {"joint.pole_hinge.damping": 0.01}
    env.close()
    again.close()


# ------------------------------------------------------------------ rendering
@pytest.mark.skipif(not can_render(), reason="set MUJOCO_GL=egl or osmesa for offscreen rendering")
@pytest.mark.parametrize("env_id", [env_param("dualtwin/CartPole-MuJoCo-v0"), env_param("dualtwin/CartPole-Webots-v0")])
def test_rgb_array_frames_are_fresh_uint8_arrays_in_both_twins(env_id: str) -> None:
    env = gym.make(env_id, render_mode="rgb_array", render_size=(24, 32))
    assert env.render_mode == "rgb_array"
    env.reset(seed=0)
    first = env.render()
    assert isinstance(first, np.ndarray) and first.shape == (24, 32, 3) and first.dtype == np.uint8
    kept = first.copy()
    env.step(env.action_space.sample())
    second = env.render()
    # A frame is the caller's: the next render does not overwrite it (RecordVideo keeps a list of them).
    assert not np.shares_memory(first, second) and np.array_equal(first, kept)
    env.close()
    env.close()


@pytest.mark.parametrize("env_id", [env_param("dualtwin/Pioneer-DriveToGoal-MuJoCo-v0"),
                                    env_param("dualtwin/Arm-Reach-MuJoCo-v0")])
def test_envs_without_a_camera_declare_no_render_mode_and_refuse_one(env_id: str) -> None:
    env = gym.make(env_id)
    assert env.metadata["render_modes"] == [] and env.render_mode is None
    env.close()
    with pytest.raises(DualtwinError, match="render_mode 'rgb_array' is not supported"):
        gym.make(env_id, render_mode="rgb_array")


# ------------------------------------------------------------------ vector envs
def _vec_pair(num_envs: int = 3, cap: int = 10) -> tuple[gym.vector.VectorEnv, gym.vector.VectorEnv]:
    kwargs: dict[str, Any] = {"max_episode_steps": cap, "task_kwargs": {"x_limit": 0.05}}
    return (gym.make_vec(CONTINUOUS, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs),
            gym.make_vec(CONTINUOUS, num_envs=num_envs, vectorization_mode="sync", **kwargs))


@pytest.mark.parametrize("env_id", [i for i in rl.registered_ids() if "MuJoCo" in i])
def test_make_vec_default_mode(env_id: str) -> None:
    """The batched env where one is registered, Gymnasium's SyncVectorEnv for the others; both declare the
    autoreset mode they honour (the default depends only on the registration: the MuJoCo ids suffice)."""
    envs = gym.make_vec(env_id, num_envs=2)
    expected = TwinVectorEnv if env_id in VECTOR_ENV_IDS else gym.vector.SyncVectorEnv
    assert isinstance(envs.unwrapped, expected)
    assert envs.metadata["autoreset_mode"] == gym.vector.AutoresetMode.NEXT_STEP
    envs.close()
    envs.close()


def test_vector_infos_are_the_sync_envs_dict_of_arrays_across_autoresets() -> None:
    """Every info key, its ``_key`` mask and dtype, on resets, steps and auto-resets (test_vector_env.py
    compares observations, rewards and flags, and one info key)."""
    batched, separate = _vec_pair()
    infos = [batched.reset(seed=5)[1], separate.reset(seed=5)[1]]
    assert data_equivalence(infos[0], infos[1], exact=True)
    assert all(isinstance(v, np.ndarray) and v.shape == (3,) for v in infos[0].values())
    assert {k for k in infos[0] if k.startswith("_")} == {f"_{k}" for k in infos[0] if not k.startswith("_")}
    actions = np.random.default_rng(2).uniform(-1, 1, (25, 3, 1)).astype(np.float32)
    resets = 0
    for action in actions:
        out_b, out_s = batched.step(action), separate.step(action)
        assert data_equivalence(out_b, out_s, exact=True)
        resets += int((out_b[2] | out_b[3]).sum())
    assert resets  # auto-resets were compared
    batched.close()
    separate.close()


def test_reset_mask_resets_only_the_masked_envs_as_sync_does() -> None:
    """Gymnasium's ``options={"reset_mask": mask}``: the batched env reset every env instead."""
    batched, separate = _vec_pair(cap=50)
    for envs in (batched, separate):
        envs.reset(seed=0)
    push = np.full((3, 1), 0.5, dtype=np.float32)
    for _ in range(4):
        before = batched.step(push)
        assert data_equivalence(before, separate.step(push), exact=True)
    mask = np.array([True, False, True])
    options = {"reset_mask": mask}
    obs_b, info_b = batched.reset(seed=10, options=options)
    obs_s, info_s = separate.reset(seed=10, options={"reset_mask": mask})
    assert "reset_mask" in options  # the caller's options are not consumed
    assert np.array_equal(obs_b, obs_s) and data_equivalence(info_b, info_s, exact=True)
    assert np.array_equal(obs_b[1], before[0][1])  # the unmasked env kept its episode
    assert info_b["_true_pole_angle"].tolist() == [True, False, True]
    for _ in range(3):
        assert data_equivalence(batched.step(push), separate.step(push), exact=True)
    for bad in (np.array([1, 0, 1]), np.array([False, False, False]), np.array([True, False])):
        with pytest.raises(ValueError, match="reset_mask"):
            batched.reset(options={"reset_mask": bad})
    batched.close()
    separate.close()


# ------------------------------------------------------------------ what training writes, read by plain SB3
def test_plain_ppo_load_reads_the_run_models(discrete_run: Path) -> None:
    from stable_baselines3 import PPO

    env = gym.make("dualtwin/CartPole-MuJoCo-v0")
    record = json.loads((discrete_run / "run.json").read_text())
    for name in ("model.zip", "best_model.zip"):
        model = PPO.load(discrete_run / name, device="cpu")
        assert model.observation_space == env.observation_space and model.action_space == env.action_space
    assert model.num_timesteps <= record["num_timesteps"]
    final = PPO.load(discrete_run / "model.zip", device="cpu")
    assert final.num_timesteps == record["num_timesteps"]
    obs, _ = env.reset(seed=0)
    action, _ = final.predict(obs, deterministic=True)
    assert env.action_space.contains(int(action))
    env.close()


def test_evaluations_npz_is_sb3s_eval_callback_log(discrete_run: Path) -> None:
    record = json.loads((discrete_run / "run.json").read_text())
    with np.load(discrete_run / "evaluations.npz") as data:
        assert set(data.files) == {"timesteps", "results", "ep_lengths"}
        n = len(record["evaluations"])
        assert data["results"].shape == data["ep_lengths"].shape == (n, TINY["eval_episodes"])
        assert data["timesteps"].tolist() == [e["timesteps"] for e in record["evaluations"]]
        assert np.allclose(data["results"].mean(axis=1), [e["mean_reward"] for e in record["evaluations"]])


def test_checkpoint_and_evaluation_frequencies_count_total_steps(discrete_run: Path) -> None:
    """SB3 counts ``save_freq``/``eval_freq`` in ``env.step`` calls (n_envs steps each, its documented trap);
    the config's frequencies are total env steps."""
    steps = sorted(int(p.name.split("_")[2]) for p in (discrete_run / "checkpoints").glob("rl_model_*_steps.zip"))
    assert steps == [1024, 2048]  # checkpoint_freq 1024, n_envs 2, 2048 steps
    with np.load(discrete_run / "evaluations.npz") as data:
        assert data["timesteps"].tolist() == [1024, 2048]


def test_saved_config_is_the_resolved_config_and_reloads(discrete_run: Path) -> None:
    from dualtwin.rl.ppo_config import load_config

    record = json.loads((discrete_run / "run.json").read_text())
    saved = load_config(discrete_run / "config.yaml")
    assert saved.model_dump(mode="json") == {**record["config"], "n_timesteps": record["total_timesteps"]}
    assert saved.n_envs == TINY["n_envs"] and saved.env_kwargs == TINY["env_kwargs"]


def test_monitor_csvs_are_sb3_monitor_files(discrete_run: Path) -> None:
    """What ``stable_baselines3.common.monitor.load_results`` (and the zoo's plot scripts) read: a ``#`` JSON
    header line, then ``r,l,t`` rows."""
    import csv

    files = sorted((discrete_run / "monitor").glob("*.monitor.csv"))
    assert len(files) == TINY["n_envs"]
    for path in files:
        first, *rest = path.read_text().splitlines()
        assert first.startswith("#") and json.loads(first[1:])["env_id"] == "dualtwin/CartPole-MuJoCo-v0"
        rows = list(csv.DictReader(rest))
        assert rows and set(rows[0]) == {"r", "l", "t"}
        assert all(0 < int(row["l"]) <= TINY["env_kwargs"]["max_episode_steps"] for row in rows)  # type: ignore[index]
