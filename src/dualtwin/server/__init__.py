"""Supervisor-free deployment (Pattern 3): the RobotServer and the robot client.

``create_app``/``serve`` (:mod:`dualtwin.server.app`) serve an exported policy plus a perception model over
HTTP (FastAPI, uvicorn, ONNX Runtime); ``deploy`` (:mod:`dualtwin.server.client`) drives a twin through a
running server with on-board sensors and camera frames only. Needs the ``server`` extra.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from dualtwin.server.app import create_app, serve
    from dualtwin.server.client import deploy

_LAZY = {"create_app": "app", "serve": "app", "deploy": "client"}


def __getattr__(name: str) -> Any:
    # Lazy: FastAPI and uvicorn load only when a server or client is used.
    if name in _LAZY:
        return getattr(importlib.import_module(f"dualtwin.server.{_LAZY[name]}"), name)
    raise AttributeError(f"module 'dualtwin.server' has no attribute {name!r}")


__all__ = ["create_app", "deploy", "serve"]
