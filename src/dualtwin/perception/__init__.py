"""Learned perception (Pattern 2): cameras on both twins, frame/ground-truth datasets, a small CNN.

``collect`` records camera frames paired with the supervisor's ground truth, ``train_perception`` fits a
CNN that recovers the privileged state from a stack of frames, ``evaluate_perception`` measures it on held-out
episodes, and the exported ``perception.onnx`` + ``perception_contract.json`` run without PyTorch
(:class:`dualtwin.perception.estimator.StateEstimator`, used by the RobotServer).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from dualtwin.perception.dataset import collect, load_dataset
    from dualtwin.perception.estimator import StateEstimator
    from dualtwin.perception.model import evaluate_perception, train_perception

# Cameras and rendering live under the twins (dualtwin.twins.camera, dualtwin.twins.render).
_LAZY = {
    "collect": "perception.dataset", "load_dataset": "perception.dataset", "StateEstimator": "perception.estimator",
    "evaluate_perception": "perception.model", "train_perception": "perception.model",
}


def __getattr__(name: str) -> Any:
    # Lazy: rendering needs MUJOCO_GL settled and training needs torch; importing the package needs neither.
    if name in _LAZY:
        return getattr(importlib.import_module(f"dualtwin.{_LAZY[name]}"), name)
    raise AttributeError(f"module 'dualtwin.perception' has no attribute {name!r}")


__all__ = ["StateEstimator", "collect", "evaluate_perception", "load_dataset", "train_perception"]
