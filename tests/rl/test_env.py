"""Env conformance over every registered dualtwin id, plus the task's semantics and domain randomisation."""

from __future__ import annotations

import re
import subprocess
import sys
import warnings
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from tests.support.rl_runs import ALL_IDS, can_render
from tests.support.tracked_twin import NAME, tracked

import dualtwin.rl as rl
from dualtwin.errors import DualtwinError
from dualtwin.rl.env import check_option
from dualtwin.rl.randomize import DomainRandomization, apply_knobs, load_knob_values, load_ranges

OBS_NAMES = ["cart_position", "cart_velocity", "pole_angle", "pole_angular_velocity"]
# The CartPole task's own checks; the Pioneer task's are in test_pioneer_task.py.
CARTPOLE_IDS = [p for p in ALL_IDS if str(p.id).startswith("CartPole")]


def rollout(env: gym.Env, seed: int, steps: int = 30) -> np.ndarray:
    env.action_space.seed(seed)
    obs, _ = env.reset(seed=seed)
    rows = [obs]
    for _ in range(steps):
        obs, reward, terminated, truncated, _ = env.step(env.action_space.sample())
        rows.append(np.append(obs, reward))
        if terminated or truncated:
            break
    return np.concatenate(rows)


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_check_env(env_id: str) -> None:
    env = gym.make(env_id)
    with warnings.catch_warnings():
        # Unbounded Box observations are deliberate (as in Gymnasium's own MuJoCo envs).
        warnings.filterwarnings("ignore", message=".*Box observation space (minimum|maximum) value is")
        check_env(env.unwrapped, skip_render_check=not can_render())
    env.close()


@pytest.mark.parametrize("env_id", CARTPOLE_IDS)
def test_spaces_and_contract(env_id: str) -> None:
    env = gym.make(env_id)
    assert env.spec is not None and env.spec.max_episode_steps == 1000
    assert env.observation_space.shape == (4,) and env.observation_space.dtype == np.float32
    contract = env.unwrapped.io_contract()
    assert [t["name"] for t in contract["observation"]["terms"]] == OBS_NAMES
    sources = {t["name"]: t["source"] for t in contract["observation"]["terms"]}
    assert sources == {"cart_position": "onboard", "cart_velocity": "onboard", "pole_angle": "onboard",
                       "pole_angular_velocity": "privileged"}
    assert contract["control_period_s"] == pytest.approx(0.032)
    if "Continuous" in env_id:
        assert isinstance(env.action_space, gym.spaces.Box) and env.action_space.shape == (1,)
        assert contract["action"]["scale"] == pytest.approx(1.5)
    else:
        assert isinstance(env.action_space, gym.spaces.Discrete) and env.action_space.n == 2
        assert contract["action"]["speed_table"] == [-1.5, 1.5]
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert abs(obs[2]) <= 0.06  # small random initial pole angle
    env.close()


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_same_seed_same_rollout(env_id: str) -> None:
    env = gym.make(env_id)
    first, second, other = rollout(env, 7), rollout(env, 7), rollout(env, 8)
    assert np.array_equal(first, second)
    assert not np.array_equal(first[:4], other[:4])
    env.close()


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_make_vec_sync(env_id: str) -> None:
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="sync")
    shape = (2, *(envs.single_observation_space.shape or ()))
    obs, _ = envs.reset(seed=3)
    assert obs.shape == shape and shape[1] >= 4
    obs, reward, terminated, truncated, _ = envs.step(envs.action_space.sample())
    assert obs.shape == shape and reward.shape == (2,)
    envs.close()


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_make_vec_async_matches_sync(env_id: str) -> None:
    """Gymnasium's async vector env (one process per env) steps each env as the sync one does: same seed and
    actions, the same observations and rewards."""
    actions = None
    results = []
    for mode in ("sync", "async"):
        envs = gym.make_vec(env_id, num_envs=2, vectorization_mode=mode)
        try:
            if actions is None:
                envs.action_space.seed(5)
                actions = [envs.action_space.sample() for _ in range(3)]
            trace = [envs.reset(seed=3)[0]]
            for action in actions:
                obs, reward, *_ = envs.step(action)
                trace += [obs, reward]
            results.append(trace)
        finally:
            envs.close()
    sync, asynchronous = results
    assert all(np.array_equal(a, b) for a, b in zip(sync, asynchronous, strict=True))
    assert not np.array_equal(sync[0][0], sync[0][1])  # the two envs were seeded apart


def test_reward_counts_balanced_steps_and_never_ends_on_the_pole() -> None:
    env = gym.make("dualtwin/CartPole-MuJoCo-v0", max_episode_steps=2000)
    assert env.spec is not None and env.spec.max_episode_steps == 2000
    env.reset(seed=0)
    env.unwrapped.twin.set_joint_state("pole_hinge", position=0.6)  # fallen beyond the 0.3 rad band
    rewards, angles = [], []
    for _ in range(40):
        _, reward, terminated, truncated, info = env.step(0 if len(rewards) % 2 else 1)
        rewards.append(reward)
        angles.append(abs(info["true_pole_angle"]))
        assert not terminated and not truncated
    # The alternating pushes may swing the pole back through the band late in the run.
    assert min(angles[:10]) > 0.3 and rewards[-1] == 0.0
    env.close()


def test_cart_leaving_the_track_terminates() -> None:
    env = gym.make("dualtwin/CartPole-MuJoCo-Continuous-v0", task_kwargs={"x_limit": 0.2})
    env.reset(seed=0)
    for _ in range(200):
        _, _, terminated, truncated, info = env.step(np.array([1.0], dtype=np.float32))
        if terminated:
            break
    assert terminated and not truncated and info["true_cart_position"] > 0.2
    env.close()


def test_discrete_action_drives_all_wheels_at_speed_over_radius() -> None:
    env = gym.make("dualtwin/CartPole-MuJoCo-v0")
    env.reset(seed=0)
    for _ in range(10):
        env.step(1)
    twin = env.unwrapped.twin
    for wheel in ("wheel1_hinge", "wheel2_hinge", "wheel3_hinge", "wheel4_hinge"):
        assert twin.joint_velocity(wheel) == pytest.approx(1.5 / 0.04, rel=0.05)
    env.close()


def test_unknown_env_id_lists_registered_ids() -> None:
    with pytest.raises(DualtwinError, match="dualtwin/CartPole-MuJoCo-v0"):
        rl.make_env("dualtwin/CartPole-Bullet-v0")
    with pytest.raises(DualtwinError, match="unknown env id"):
        rl.check_env_id("CartPole-v1")


@pytest.mark.skipif(not can_render(), reason="set MUJOCO_GL=egl or osmesa for offscreen rendering")
def test_render_rgb_array() -> None:
    env = gym.make("dualtwin/CartPole-MuJoCo-v0", render_mode="rgb_array", render_size=(48, 64))
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (48, 64, 3) and frame.dtype == np.uint8
    env.close()


# ------------------------------------------------------------------ domain randomisation and aligned knobs
RANGES = {"knobs": {
    "body.pole.mass": {"nominal": 0.2, "fitted": 0.25, "low": 0.15, "high": 0.35, "distribution": "uniform"},
    "joint.pole_hinge.damping": {"low": 0.001, "high": 0.1, "distribution": "log_uniform"},
    "geom.floor.friction": {"low": 0.8, "high": 1.2, "operation": "scale"},
}}


def _model_values(env: gym.Env) -> dict[str, float]:
    import mujoco

    twin = env.unwrapped.twin
    m = twin.model
    pole = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "pole")
    hinge = m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "pole_hinge")]
    floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    return {"body.pole.mass": float(m.body_mass[pole]), "joint.pole_hinge.damping": float(m.dof_damping[hinge]),
            "geom.floor.friction": float(m.geom_friction[floor, 0]),
            "pole_inertia": float(m.body_inertia[pole, 0])}


def test_dr_draws_from_nominal_and_never_compounds() -> None:
    env = DomainRandomization(gym.make("dualtwin/CartPole-MuJoCo-v0"), RANGES)
    nominal_inertia = _model_values(env)["pole_inertia"]
    floor_nominal = env.unwrapped.twin.knobs()["geom.floor.friction"].nominal
    draws = []
    for episode in range(12):
        _, info = env.reset(seed=100 + episode)
        draw = info["dr"]
        draws.append(draw)
        actual = _model_values(env)
        assert 0.15 <= draw["body.pole.mass"] <= 0.35
        assert 0.001 <= draw["joint.pole_hinge.damping"] <= 0.1
        assert 0.8 * floor_nominal <= draw["geom.floor.friction"] <= 1.2 * floor_nominal
        for name in RANGES["knobs"]:
            assert actual[name] == pytest.approx(draw[name])
        # Inertia scales with the drawn mass from the *nominal* inertia: no drift across episodes.
        assert actual["pole_inertia"] == pytest.approx(nominal_inertia * draw["body.pole.mass"] / 0.2)
        for _ in range(3):
            env.step(env.action_space.sample())
    assert len({d["body.pole.mass"] for d in draws}) == len(draws)


def test_dr_is_reproducible_from_the_reset_seed() -> None:
    a = DomainRandomization(gym.make("dualtwin/CartPole-MuJoCo-v0"), RANGES)
    b = DomainRandomization(gym.make("dualtwin/CartPole-MuJoCo-v0"), RANGES)
    assert a.reset(seed=5)[1]["dr"] == b.reset(seed=5)[1]["dr"]
    assert a.reset()[1]["dr"] == b.reset()[1]["dr"]


def test_dr_rejects_unknown_knobs_and_bad_ranges(tmp_path) -> None:  # type: ignore[no-untyped-def]
    env = gym.make("dualtwin/CartPole-MuJoCo-v0")
    with pytest.raises(DualtwinError, match="no knobs named body.nope.mass"):
        DomainRandomization(env, {"knobs": {"body.nope.mass": {"low": 1, "high": 2}}})
    with pytest.raises(DualtwinError, match="low"):
        load_ranges({"knobs": {"body.pole.mass": {"low": 2, "high": 1}}})
    with pytest.raises(DualtwinError, match="log_uniform needs low > 0"):
        load_ranges({"knobs": {"joint.pole_hinge.damping": {"low": 0, "high": 1, "distribution": "log_uniform"}}})
    with pytest.raises(DualtwinError, match="bounds"):
        DomainRandomization(env, {"knobs": {"body.pole.mass": {"low": 0.1, "high": 50.0}}})
    with pytest.raises(DualtwinError, match="not found"):
        load_ranges(tmp_path / "missing.json")


def test_aligned_knobs_apply_at_every_reset(tmp_path) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "aligned.json"
    path.write_text('{"knobs": {"body.pole.mass": {"nominal": 0.2, "fitted": 0.3}}}')
    assert load_knob_values(path) == {"body.pole.mass": 0.3}
    assert load_knob_values({"joint.pole_hinge.damping": 0.05}) == {"joint.pole_hinge.damping": 0.05}
    env = apply_knobs(gym.make("dualtwin/CartPole-MuJoCo-v0"), path)
    for seed in range(3):
        _, info = env.reset(seed=seed)
        assert info["knobs"] == {"body.pole.mass": 0.3}
        assert _model_values(env)["body.pole.mass"] == pytest.approx(0.3)
    with pytest.raises(DualtwinError, match="finite number"):
        load_knob_values({"body.pole.mass": "heavy"})


def test_reset_without_knob_options_returns_to_the_env_knobs() -> None:
    env = gym.make("dualtwin/CartPole-MuJoCo-v0", knobs={"body.pole.mass": 0.3})
    env.reset(seed=0, options={"knobs": {"body.pole.mass": 0.25}})
    assert _model_values(env)["body.pole.mass"] == pytest.approx(0.25)
    env.reset(seed=0)
    assert _model_values(env)["body.pole.mass"] == pytest.approx(0.3)
    with pytest.raises(DualtwinError, match="no knobs named"):
        gym.make("dualtwin/CartPole-MuJoCo-v0", knobs={"body.nope.mass": 1.0})


def test_odometry_cart_velocity_is_onboard() -> None:
    env = gym.make("dualtwin/CartPole-MuJoCo-Continuous-v0")
    terms = env.unwrapped.io_contract()["observation"]["terms"]
    assert [t["name"] for t in terms] == OBS_NAMES and terms[1]["source"] == "onboard"
    env.reset(seed=0)
    for _ in range(15):
        obs, *_ = env.step(np.array([0.5], dtype=np.float32))
    # The wheels turn at the commanded 0.75 m/s (odometry velocity = wheel speed x radius).
    assert obs[1] == pytest.approx(0.75, rel=0.02)
    with pytest.raises(DualtwinError, match="cart_velocity"):
        gym.make("dualtwin/CartPole-MuJoCo-v0", task_kwargs={"cart_velocity": "radar"})


@pytest.mark.parametrize("env_id", CARTPOLE_IDS)
def test_ground_truth_variant_observations_are_finite(env_id: str) -> None:
    env = gym.make(env_id, task_kwargs={"cart_velocity": "ground_truth"})
    obs, _ = env.reset(seed=0)
    assert np.isfinite(obs).all()
    obs, *_ = env.step(env.action_space.sample())
    assert np.isfinite(obs).all()
    env.close()


def test_no_reward_while_the_cart_is_tipped_over(monkeypatch: pytest.MonkeyPatch) -> None:
    """A cart on its back keeps the hinge angle in the band with nothing balanced; that must earn nothing."""
    env = gym.make("dualtwin/CartPole-MuJoCo-v0")
    env.reset(seed=0)
    _, reward, *_ , info = env.step(1)
    assert reward == 1.0 and info["true_cart_tilt"] < 0.2
    twin = env.unwrapped.twin
    flipped = np.diag([1.0, -1.0, -1.0])
    monkeypatch.setattr(twin, "body_orientation", lambda body: flipped)
    _, reward, terminated, _, info = env.step(0)
    assert abs(info["true_pole_angle"]) <= 0.3 and info["true_cart_tilt"] == pytest.approx(np.pi)
    assert reward == 0.0 and not terminated
    contract = env.unwrapped.io_contract()
    assert contract["task"]["upright_angle_rad"] == pytest.approx(0.5)


def test_integer_knobs_draw_every_value_alike() -> None:
    from dualtwin.rl.randomize import draw_knobs

    ranges = load_ranges({"knobs": {"control.delay_periods": {"low": 0, "high": 2, "integer": True}}})
    rng = np.random.default_rng(0)
    draws = [draw_knobs(ranges, {"control.delay_periods": 0.0}, rng)["control.delay_periods"] for _ in range(3000)]
    values, counts = np.unique(draws, return_counts=True)
    # Rounding a uniform float would give 0 and 2 a quarter each, 1 a half.
    assert values.tolist() == [0.0, 1.0, 2.0] and np.all(np.abs(counts / 3000 - 1 / 3) < 0.04)
    with pytest.raises(DualtwinError, match="no integer"):
        load_ranges({"knobs": {"control.delay_periods": {"low": 0.2, "high": 0.8, "integer": True}}})


@pytest.mark.parametrize(("options", "message"), [
    ({"pole_joint": None}, r"task_kwargs\.pole_joint: Input should be a valid string"),
    ({"observation_ranges": "abc"}, r"task_kwargs\.observation_ranges: Input should be a valid list"),
    ({"action_key": []}, r"task_kwargs\.action_key: Input should be a valid string"),
    ({"x_limit": float("nan")}, r"task_kwargs\.x_limit: Input should be a finite number"),
    ({"initial_angle": 1e308}, "initial_angle from 0 to pi"),
    ({"continuous": True}, r"task 'cartpole_balance': task_kwargs\.continuous: not an option of this task"),
])
def test_hostile_task_options_are_named(options: dict[str, object], message: str) -> None:
    """Checked against the task's annotations: pole_joint None killed the process (SIGSEGV in mj_name2id), the
    next two were tracebacks, NaN was accepted and 1e308 overflowed numpy's uniform draw at reset (fuzzing).
    In a child process, so that the SIGSEGV the old code died of fails this test rather than the test run."""
    code = ("import gymnasium as gym, dualtwin.rl\n"
            f"env = gym.make('dualtwin/CartPole-MuJoCo-Continuous-v0', task_kwargs={options!r})\n"
            "env.reset(seed=0)\n")
    done = subprocess.run([sys.executable, "-c", code.replace("nan", "float('nan')")], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 1, done.stderr
    assert re.search(f"DualtwinError: .*{message}", done.stderr.strip().splitlines()[-1]), done.stderr


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"knobs": "abc"}, "knobs must be a mapping"),
    ({"knobs": {"body.pole.mass": "abc"}}, "knob 'body.pole.mass' must be a finite number"),
    ({"knobs": {"body.pole.mass": float("nan")}}, "knob 'body.pole.mass' must be a finite number"),
    ({"control_period": "abc"}, r"control_period must be a number of seconds in \(0, 60\]"),
    ({"control_period": None}, r"control_period must be a number of seconds in \(0, 60\]"),
])
def test_hostile_env_arguments_are_named(kwargs: dict[str, object], message: str) -> None:
    """The first, second and last two were ValueError/TypeError tracebacks, NaN went into the model (fuzzing)."""
    with pytest.raises(DualtwinError, match=message):
        gym.make("dualtwin/CartPole-MuJoCo-v0", **kwargs).reset(seed=0)


def test_hostile_reset_knobs_are_named() -> None:
    env = gym.make("dualtwin/CartPole-MuJoCo-v0")
    with pytest.raises(DualtwinError, match=r"reset options\["):
        env.reset(seed=0, options={"knobs": ["body.pole.mass"]})
    env.close()


@pytest.mark.parametrize(("value", "hint", "message"), [
    ({"a": [1.0, float("nan")]}, dict[str, Any], r"^\$\.o\.a\.1: must be finite, got nan$"),
    ([float("inf")], list[float], r"^\$\.o: Input should be a finite number"),
    ("0.5", float, r"^\$\.o: Input should be a valid number"),
    (1, bool, r"^\$\.o: Input should be a valid boolean"),
])
def test_check_option_is_strict_and_finite(value: Any, hint: Any, message: str) -> None:
    """The one option check (task options, the options a server sets): strict types, and no NaN or infinity even
    inside values an annotation leaves open (Any), which pydantic passes through."""
    with pytest.raises(DualtwinError, match=message):
        check_option("$.o", value, hint)
    assert check_option("$.o", {"a": [1.0, 2]}, dict[str, Any]) == {"a": [1.0, 2]}


@pytest.mark.parametrize(("arguments", "message"), [
    ({"knobs": {"no.such.knob": 1.0}}, "no.such.knob"),
    ({"render_mode": "human"}, "render_mode 'human' is not supported"),
    ({"task_kwargs": {"action_key": "no_such_action"}}, "needs a velocity action .no_such_action."),
])
def test_a_refusal_after_the_twin_is_built_closes_it(arguments: dict[str, Any], message: str) -> None:
    """These arguments are refused only once the twin exists (knob names, render modes and the task's binding
    names): the env closes the twin it built, where it was left open until the process ended (a Webots twin
    keeps its ODE world)."""
    with tracked() as built:
        with pytest.raises(DualtwinError, match=message):
            rl.TwinEnv(NAME, "cartpole", "cartpole_balance", **arguments)
        assert len(built) == 1 and built[0].closed
        env = rl.TwinEnv(NAME, "cartpole", "cartpole_balance")  # accepted arguments: the twin stays open
        assert len(built) == 2 and not built[1].closed
        env.close()
        assert built[1].closed
