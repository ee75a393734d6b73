"""Webots tests never touch the user's PROTO cache, Webots' asset cache or the network by accident."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(autouse=True)
def _isolated_proto_cache(monkeypatch: pytest.MonkeyPatch, tmp_path_factory: pytest.TempPathFactory) -> Path:
    cache_home = tmp_path_factory.mktemp("xdg-cache")
    monkeypatch.setenv("XDG_CACHE_HOME", str(cache_home))
    monkeypatch.setenv("DUALTWIN_PROTO_OFFLINE", "1")
    monkeypatch.delenv("DUALTWIN_PROTO_CACHE", raising=False)
    monkeypatch.delenv("DUALTWIN_PROTO_MIRROR", raising=False)
    return cache_home
