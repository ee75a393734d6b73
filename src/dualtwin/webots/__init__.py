"""The Webots twin: world/PROTO parsing and expansion, and the headless ODE runner."""

from __future__ import annotations

from dualtwin.webots.lexer import WebotsSyntaxError
from dualtwin.webots.nodes import Node, SourceLocation, World
from dualtwin.webots.proto_resolver import ProtoError, ProtoNotFoundError
from dualtwin.webots.protos import load_world, load_world_text

__all__ = [
    "Node",
    "ProtoError",
    "ProtoNotFoundError",
    "SourceLocation",
    "WebotsSyntaxError",
    "World",
    "load_world",
    "load_world_text",
]
