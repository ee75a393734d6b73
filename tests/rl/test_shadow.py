"""The Webots shadow of MuJoCo training: a sampled fraction of episodes mirrored, divergence logged."""

from __future__ import annotations

import csv
from pathlib import Path


def test_shadow_callback_logs_divergence_scalars(tmp_path: Path) -> None:
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.logger import configure

    from dualtwin.rl import make_env
    from dualtwin.rl.shadow import ShadowCallback

    venv = make_vec_env(lambda: make_env("dualtwin/CartPole-MuJoCo-v0", max_episode_steps=30), n_envs=2, seed=0)
    model = PPO("MlpPolicy", venv, n_steps=48, batch_size=48, n_epochs=1, seed=0, device="cpu",
                policy_kwargs={"net_arch": [8]})
    model.set_logger(configure(str(tmp_path), ["csv"]))
    shadow = ShadowCallback(fraction=1.0, seed=0)
    model.learn(total_timesteps=96, callback=shadow)
    with open(tmp_path / "progress.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    columns = set(rows[-1])
    for key in ("shadow/error_mean", "shadow/error_max", "shadow/periods", "shadow/episodes",
                "shadow/sync_failures", "shadow/error_h1", "shadow/episode_error_mean"):
        assert key in columns, key
    assert any(c.startswith("shadow/channel/") for c in columns)
    last = rows[-1]
    # Two envs, 48 steps each per rollout, 30-step episodes: one shadow at a time, every free start sampled.
    assert int(float(last["shadow/episodes"])) >= 2 and int(float(last["shadow/periods"])) > 30
    assert 0 < float(last["shadow/error_mean"]) < 5
    assert shadow.sync_failures == 0


def test_shadow_feeds_a_sync_monitor_through_its_protocol(tmp_path: Path) -> None:
    """rl.shadow does not import sync: a real sync.Monitor is fed through the DriftMonitor protocol.

    The monitor must see every shadowed episode (start, one window event per window of periods) and log them
    next to the SB3 logs; with a window longer than any episode it logs no window events (the control).
    """
    import json

    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.logger import configure

    from dualtwin.rl import make_env
    from dualtwin.rl.shadow import DriftMonitor, ShadowCallback
    from dualtwin.sync import Monitor, MonitorConfig

    def run(window: int, out: Path) -> tuple[ShadowCallback, list[dict[str, object]]]:
        venv = make_vec_env(lambda: make_env("dualtwin/CartPole-MuJoCo-v0", max_episode_steps=30), n_envs=2, seed=0)
        model = PPO("MlpPolicy", venv, n_steps=48, batch_size=48, n_epochs=1, seed=0, device="cpu",
                    policy_kwargs={"net_arch": [8]})
        model.set_logger(configure(str(out), ["csv"]))
        monitor: DriftMonitor = Monitor(MonitorConfig(window=window, high=100.0, low=50.0))
        shadow = ShadowCallback(fraction=1.0, seed=0, monitor=monitor)
        model.learn(total_timesteps=96, callback=shadow)
        lines = (out / "shadow_monitor_events.jsonl").read_text(encoding="utf-8").splitlines()
        return shadow, [json.loads(line) for line in lines]

    shadow, events = run(5, tmp_path / "short")
    kinds = [e["event"] for e in events]
    assert kinds[0] == "monitor_started"
    windows = [e for e in events if e["event"] == "window"]
    assert len(windows) >= shadow.periods // 5 - shadow.episodes  # every full window of every episode
    assert {e["episode"] for e in windows} <= {f"shadow{i:05d}" for i in range(1, shadow.episodes + 1)}
    _, control = run(1000, tmp_path / "long")
    assert [e for e in control if e["event"] == "window"] == []
