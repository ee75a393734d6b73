"""Fixtures for the perception tests: headless rendering, one tiny dataset and one tiny model per session."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

# Tests may choose a default backend (library code never does): Mesa EGL, headless, no GPU. MuJoCo reads the
# variable when it is first imported; once another test module has imported it, leave the environment alone
# (other tests read it to decide whether rendering is available).
if "mujoco" not in sys.modules:
    os.environ.setdefault("MUJOCO_GL", "egl")

EPISODES, STEPS, SIZE = 6, 40, 48


def _can_render() -> str | None:
    try:
        import mujoco

        from dualtwin.twins.camera import FrameRenderer

        model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='1'/></worldbody></mujoco>")
        FrameRenderer(model, 8, 8).close()
    except Exception as exc:  # noqa: BLE001 - any failure means: no headless GL here
        return f"{type(exc).__name__}: {exc}"
    return None


@pytest.fixture(scope="session")
def headless() -> None:
    problem = _can_render()
    if problem is not None:
        pytest.skip(f"headless rendering unavailable (MUJOCO_GL={os.environ.get('MUJOCO_GL')}): {problem}")


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory: pytest.TempPathFactory, headless: None) -> Path:
    from dualtwin.perception.dataset import collect

    out = tmp_path_factory.mktemp("perception") / "data"
    # Random actions: the pole falls and the cart wanders, so a few epochs have a large signal to learn.
    return collect("dualtwin/CartPole-MuJoCo-Continuous-v0", EPISODES, out, controller="random", max_steps=STEPS,
                   width=SIZE, height=SIZE, episodes_per_shard=2, seed=3)


@pytest.fixture(scope="session")
def tiny_model(tmp_path_factory: pytest.TempPathFactory, tiny_dataset: Path) -> Path:
    import torch

    from dualtwin.perception.model import train_perception

    torch.set_num_threads(1)
    out = tmp_path_factory.mktemp("perception") / "model"
    return train_perception(tiny_dataset, out, epochs=40, seed=0, threads=1, holdout=0.34, batch_size=16,
                            learning_rate=3e-3)
