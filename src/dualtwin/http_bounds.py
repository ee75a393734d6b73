"""HTTP clients whose replies end: a whole body within a time and a size, not only each read.

The HTTP layer's timeouts (httpx's, and those of the client libraries built on it) bound each read, not the body:
a server that sends a byte now and then kept the caller waiting forever, and a fast endless body filled the
memory. A server is not trusted (an LLM provider, a RobotServer someone else runs, a wrong URL), so the clients
that talk to one are made here: :func:`bounded_client` wraps each response's byte stream as its headers arrive
and checks every chunk. The errors raised are the HTTP layer's own (a read timeout, a read error marked
``dualtwin_reply_limit``), so the caller's retries and error handling treat them as any other failed read.
"""

from __future__ import annotations

import importlib
import time
from types import ModuleType
from typing import Any

__all__ = ["bounded_client", "is_reply_limit"]


def _http_module(factory: type) -> ModuleType:
    """The HTTP package a client class builds on: the first of its bases whose top-level package has httpx's
    stream and error classes (``httpx.Client`` itself, or a library's subclass of it)."""
    for cls in factory.__mro__:
        module = importlib.import_module(cls.__module__.partition(".")[0])
        if all(hasattr(module, name) for name in ("SyncByteStream", "ReadTimeout", "ReadError")):
            return module
    raise TypeError(f"{factory.__name__} is not an httpx client class")


def bounded_client(factory: type, *, reply_s: float, max_bytes: int, **kwargs: Any) -> Any:
    """``factory(**kwargs)`` (an httpx ``Client`` class or a subclass) whose every reply body must arrive within
    ``reply_s`` seconds of its headers and hold at most ``max_bytes``."""
    http = _http_module(factory)

    class ReplyTooLarge(http.ReadError):  # type: ignore[name-defined,misc]
        dualtwin_reply_limit = True

    class Bounded(http.SyncByteStream):  # type: ignore[name-defined,misc]
        def __init__(self, inner: Any) -> None:
            self.inner, self.deadline = inner, time.monotonic() + reply_s

        def __iter__(self) -> Any:
            size = 0
            for chunk in self.inner:
                size += len(chunk)
                if size > max_bytes:
                    raise ReplyTooLarge(f"reply body larger than {max_bytes} bytes")
                if time.monotonic() > self.deadline:
                    raise http.ReadTimeout(f"the reply did not end within {reply_s:g} s")
                yield chunk

        def close(self) -> None:
            self.inner.close()

    def bound(response: Any) -> None:  # called with the headers, before the body is read
        response.stream = Bounded(response.stream)

    hooks = dict(kwargs.pop("event_hooks", None) or {})
    hooks["response"] = [*hooks.get("response", []), bound]
    return factory(event_hooks=hooks, **kwargs)


def is_reply_limit(exc: BaseException | None) -> bool:
    """Whether ``exc`` (or what it wraps) is :func:`bounded_client`'s size limit."""
    seen: set[int] = set()
    while exc is not None and id(exc) not in seen:
        if getattr(exc, "dualtwin_reply_limit", False):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False
