"""A controller that is a Gym environment too, as RL users write them for Webots (deepbots' RobotSupervisorEnv and
the paper's CartPole controllers follow this pattern): one class inheriting ``Supervisor`` and ``gymnasium.Env``,
whose own ``step(action)`` and ``reset()`` shadow ``Robot.step`` and which reaches Webots' step through
``super(Supervisor, self).step(ms)``; a ``timestep`` property over ``self._timestep``; ``close``, ``np_random`` and
``metadata`` from ``gymnasium.Env``; and a reset by ``simulationReset()`` + ``simulationResetPhysics()`` + one basic
step. Webots' Robot defines none of those names, so the runtime must not call ``self.step`` or use these attributes
itself. Expected, from on-ODE §6: the reset is applied at the end of the step it was asked in, so the time read after
it is 0 and every episode from the same action sequence is the same; both controller modes print the same."""

from __future__ import annotations

from pathlib import Path

from tests.support.isolation_runs import run_in_both_modes

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = """
import gymnasium
import numpy as np
from controller import Supervisor


class CartPoleEnv(Supervisor, gymnasium.Env):
    metadata = {"render_modes": []}

    def __init__(self):
        super().__init__()
        self.timestep = self.getBasicTimeStep()
        self.observation_space = gymnasium.spaces.Box(-np.inf, np.inf, (3,), np.float64)
        self.action_space = gymnasium.spaces.Discrete(2)
        self.sensor = self.getDevice("pole sensor")
        self.sensor.enable(self.timestep)
        self.wheels = [self.getDevice(f"wheel{i}") for i in range(1, 5)]
        self.cart = self.getSelf()

    @property
    def timestep(self):
        return self._timestep

    @timestep.setter
    def timestep(self, value):
        self._timestep = int(value)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.simulationReset()
        self.simulationResetPhysics()
        super(Supervisor, self).step(int(self.getBasicTimeStep()))
        return self.observe(), {}

    def observe(self):
        return np.array([self.cart.getPosition()[0], self.cart.getVelocity()[0], self.sensor.getValue()])

    def step(self, action):
        for wheel in self.wheels:
            wheel.setPosition(float("inf"))
            wheel.setVelocity(5.0 if action == 0 else -5.0)
        if super(Supervisor, self).step(self.timestep) == -1:
            raise SystemExit(0)
        obs = self.observe()
        return obs, 1.0, bool(abs(obs[2]) > 0.26), False, {}


env = CartPoleEnv()
for episode in range(2):
    obs, _ = env.reset(seed=episode)
    print("reset", round(env.getTime(), 6), obs.round(6).tolist(), int(env.np_random.integers(0, 1)))
    done, steps = False, 0
    while not done and steps < 200:
        obs, reward, done, truncated, info = env.step(steps // 10 % 2)
        steps += 1
    print("episode", steps, round(env.getTime(), 6), obs.round(6).tolist())
env.close()
env.simulationQuit(0)
super(Supervisor, env).step(env.timestep)
"""


def test_a_supervisor_that_is_a_gymnasium_env_runs_and_resets_in_both_modes(tmp_path: Path) -> None:
    world = (ROOT / "src/dualtwin/robots/cartpole/cartpole.wbt").read_text(encoding="utf-8")
    world = world.replace('controller "<extern>"', 'controller "probe"')
    assert 'controller "probe"' in world and "supervisor TRUE" in world
    runs = run_in_both_modes(tmp_path, world, SCRIPT, duration_s=20.0)
    assert runs["threads"].code == 0, runs["threads"].err
    lines = runs["threads"].out.splitlines()
    resets = [line for line in lines if line.startswith("reset")]
    episodes = [line for line in lines if line.startswith("episode")]
    assert resets == ["reset 0.0 [0.0, 0.0, 0.0] 0"] * 2  # time 0 and the load state after each reset
    assert len(episodes) == 2 and episodes[0] == episodes[1]  # the same actions give the same episode
    assert int(episodes[0].split()[1]) > 10  # it ran (the pole fell or the 200 steps passed)
    assert runs["process"] == runs["threads"]
