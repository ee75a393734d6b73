"""LLM providers behind one interface: OpenAI-compatible chat completions and Anthropic messages.

``provider: openai`` uses the ``openai`` client with a ``base_url``, which covers OpenAI itself and every server
speaking the chat-completions API (Ollama ``http://localhost:11434/v1``, vLLM, llama.cpp server, LM Studio).
``provider: anthropic`` uses the ``anthropic`` client (``base_url`` for proxies/compatible gateways).

Configuration (later sources win): a YAML file (``DUALTWIN_LLM_CONFIG`` or an explicit path) with keys
``provider, model, base_url, api_key_env, timeout_s, max_retries, temperature, max_tokens, json_mode``; then the
environment: ``DUALTWIN_LLM_PROVIDER``, ``DUALTWIN_LLM_BASE_URL``, ``DUALTWIN_LLM_MODEL`` and the key from
``DUALTWIN_LLM_API_KEY``, else ``OPENAI_API_KEY`` / ``ANTHROPIC_API_KEY`` (by provider), else the variable named
by ``api_key_env``. Keys are never logged: ``repr`` shows ``***`` and :meth:`LLMConfig.redact` scrubs
transcripts. Calls have a timeout and a bounded number of retries (the client libraries' backoff); an
unreachable provider, an error status or a timeout raises :class:`~dualtwin.errors.DualtwinError`.
"""

from __future__ import annotations

import json
import os
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any, Literal, TypedDict

from dualtwin.artifacts import read_yaml
from dualtwin.errors import DualtwinError
from dualtwin.http_bounds import bounded_client, is_reply_limit

Provider = Literal["openai", "anthropic"]
JsonMode = Literal["auto", "json_object", "json_schema", "off"]

ENV_PROVIDER = "DUALTWIN_LLM_PROVIDER"
ENV_BASE_URL = "DUALTWIN_LLM_BASE_URL"
ENV_MODEL = "DUALTWIN_LLM_MODEL"
ENV_API_KEY = "DUALTWIN_LLM_API_KEY"
ENV_CONFIG = "DUALTWIN_LLM_CONFIG"
PROVIDER_KEY_ENV = {"openai": "OPENAI_API_KEY", "anthropic": "ANTHROPIC_API_KEY"}
#: Upper bound on one reply: anything larger is rejected before it is parsed.
MAX_RESPONSE_CHARS = 200_000
#: Upper bound on one reply's HTTP body, read as it arrives: the text's limit with room for JSON escapes
#: (``\uXXXX`` is 6 bytes a character) and the envelope.
MAX_REPLY_BYTES = 8 * MAX_RESPONSE_CHARS + 65_536
# Local servers (Ollama, llama.cpp) ignore the key but the client libraries insist on one.
NO_KEY = "not-needed"


class Message(TypedDict):
    role: Literal["system", "user", "assistant"]
    content: str


@dataclass(frozen=True)
class LLMConfig:
    """Which provider and model to call, and how patiently."""

    provider: Provider = "openai"
    model: str = ""
    base_url: str | None = None
    api_key: str | None = None
    timeout_s: float = 60.0
    max_retries: int = 2
    temperature: float = 0.0
    max_tokens: int = 4096
    json_mode: JsonMode = "auto"

    def __repr__(self) -> str:
        shown = ", ".join(f"{f.name}={'***' if f.name == 'api_key' and self.api_key else repr(getattr(self, f.name))}"
                          for f in fields(self))
        return f"LLMConfig({shown})"

    __str__ = __repr__

    def redact(self, text: str) -> str:
        """``text`` with the API key replaced by ``***`` (for transcripts and error messages)."""
        key = self.api_key
        if key and key != NO_KEY and len(key) >= 4:
            text = text.replace(key, "***")
        return text

    @property
    def where(self) -> str:
        # The address and where it is set (the environment, else the config file's base_url), so a wrong one
        # is found at once.
        at = (f"{self.base_url} ({ENV_BASE_URL} or base_url in {ENV_CONFIG})" if self.base_url
              else "its default URL")
        return f"{self.provider} provider at {at} (model {self.model!r})"


_FILE_KEYS = {"provider", "model", "base_url", "api_key", "api_key_env", "timeout_s", "max_retries", "temperature",
              "max_tokens", "json_mode"}


def load_llm_config(path: Path | str | None = None, env: Mapping[str, str] | None = None) -> LLMConfig:
    """Build the configuration from an optional YAML file and the environment (see the module docstring)."""
    env = os.environ if env is None else env
    data: dict[str, Any] = {}
    path = path or env.get(ENV_CONFIG)
    if path:
        p = Path(path)
        if not p.is_file():
            raise DualtwinError(f"{p}: LLM config file not found")
        # A binary file, a pipe, a deep or huge file: one line naming it (the shared careful reader).
        loaded = read_yaml(p, "LLM config file") or {}
        if not isinstance(loaded, dict):
            raise DualtwinError(f"{p}: LLM config must be a mapping")
        unknown = sorted(set(loaded) - _FILE_KEYS)
        if unknown:
            raise DualtwinError(f"{p}: unknown LLM config keys {unknown} (known: {sorted(_FILE_KEYS)})")
        data = dict(loaded)
    key_env = data.pop("api_key_env", None)
    if env.get(ENV_PROVIDER):
        data["provider"] = env[ENV_PROVIDER]
    if env.get(ENV_BASE_URL):
        data["base_url"] = env[ENV_BASE_URL]
    if env.get(ENV_MODEL):
        data["model"] = env[ENV_MODEL]
    provider = str(data.get("provider", "openai")).lower()
    if provider not in ("openai", "anthropic"):
        raise DualtwinError(f"unknown LLM provider {provider!r}: use 'openai' (any OpenAI-compatible server) "
                            "or 'anthropic'")
    data["provider"] = provider
    key = env.get(ENV_API_KEY) or env.get(PROVIDER_KEY_ENV[provider]) or (env.get(str(key_env)) if key_env else None)
    if key:
        data["api_key"] = key
    if not data.get("model"):
        raise DualtwinError(f"no LLM model configured: set {ENV_MODEL} (and {ENV_PROVIDER}, {ENV_BASE_URL}) or "
                            f"give a config file with 'model'")
    try:
        config = LLMConfig(**data)
    except TypeError as exc:
        raise DualtwinError(f"invalid LLM configuration: {exc}") from None
    numbers = (config.timeout_s > 0, config.max_retries >= 0, config.max_tokens > 0)
    if not all(numbers):
        raise DualtwinError("LLM timeout_s and max_tokens must be positive and max_retries >= 0")
    return config


class LLMClient(ABC):
    """One chat call: messages in, the reply text out."""

    def __init__(self, config: LLMConfig) -> None:
        self.config = config

    @abstractmethod
    def complete(self, messages: list[Message], *, json_schema: dict[str, Any] | None = None) -> str:
        """The assistant's reply. ``json_schema`` asks for JSON output where the provider supports it."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.config!r})"

    def _check_size(self, text: str) -> str:
        if len(text) > MAX_RESPONSE_CHARS:
            raise DualtwinError(f"{self.config.where}: reply of {len(text)} characters exceeds the "
                                f"{MAX_RESPONSE_CHARS} limit")
        return text

    def _unreadable(self, exc: json.JSONDecodeError | RecursionError) -> DualtwinError:
        """A reply body that is not JSON (a proxy's HTML page, a broken or hostile server) or nested too deeply."""
        why = (f"{exc.msg} at line {exc.lineno} column {exc.colno}" if isinstance(exc, json.JSONDecodeError)
               else "nested too deeply")
        return DualtwinError(f"{self.config.where}: the reply is not a JSON document ({why})")

    def _error(self, exc: Exception) -> DualtwinError:
        """A user-facing error for a failed call (timeout, connection, HTTP status, a reply too large)."""
        cfg = self.config
        name = type(exc).__name__
        status = getattr(exc, "status_code", None)
        tries = cfg.max_retries + 1
        if is_reply_limit(exc.__cause__):  # (the clients wrap the HTTP layer's error)
            text = f"{cfg.where}: {exc.__cause__} ({tries} attempt(s))"
        elif "Timeout" in name:
            text = f"{cfg.where}: request timed out after {cfg.timeout_s:g} s ({tries} attempt(s))"
        elif status is not None:
            detail = " ".join(str(getattr(exc, "message", exc)).split())[:300]
            text = f"{cfg.where}: HTTP {status} error after {tries} attempt(s): {detail}"
        else:
            text = (f"{cfg.where}: cannot connect ({' '.join(str(exc).split())[:200]}) after {tries} attempt(s); "
                    "is the server running and the base URL right?")
        return DualtwinError(cfg.redact(text))


class OpenAIChatClient(LLMClient):
    """Chat completions through the ``openai`` client (OpenAI, Ollama, vLLM, llama.cpp, LM Studio)."""

    def __init__(self, config: LLMConfig) -> None:
        super().__init__(config)
        try:
            import openai
        except ImportError as exc:  # pragma: no cover - extras not installed
            raise DualtwinError("the 'openai' package is needed: pip install 'dualtwin[llm]'") from exc
        self._openai = openai
        http = bounded_client(openai.DefaultHttpxClient, reply_s=config.timeout_s, max_bytes=MAX_REPLY_BYTES)
        self._client = openai.OpenAI(api_key=config.api_key or NO_KEY, base_url=config.base_url,
                                     timeout=config.timeout_s, max_retries=config.max_retries, http_client=http)
        self._json_mode: JsonMode = config.json_mode

    def _response_format(self, json_schema: dict[str, Any] | None) -> dict[str, Any] | None:
        if json_schema is None or self._json_mode == "off":
            return None
        if self._json_mode == "json_schema":
            return {"type": "json_schema", "json_schema": {"name": "robot_description", "schema": json_schema}}
        return {"type": "json_object"}

    def complete(self, messages: list[Message], *, json_schema: dict[str, Any] | None = None) -> str:
        openai = self._openai
        fmt = self._response_format(json_schema)
        kwargs: dict[str, Any] = {"model": self.config.model, "messages": list(messages),
                                  "temperature": self.config.temperature, "max_tokens": self.config.max_tokens}
        # The typed overloads of create() do not accept a kwargs dict.
        create: Any = self._client.chat.completions.create
        try:
            try:
                response = create(**kwargs, **({"response_format": fmt} if fmt else {}))
            except openai.BadRequestError as exc:
                # Servers without JSON mode reject response_format: fall back to extracting the JSON block.
                if fmt is None or self._json_mode != "auto" or "response_format" not in str(exc):
                    raise
                self._json_mode = "off"
                response = create(**kwargs)
        except (openai.APIConnectionError, openai.APIStatusError) as exc:
            raise self._error(exc) from None
        except (json.JSONDecodeError, RecursionError) as exc:
            raise self._unreadable(exc) from None
        content = _chat_content(response)
        if content is None:
            raise DualtwinError(f"{self.config.where}: reply has no text content")
        return self._check_size(content)


class AnthropicClient(LLMClient):
    """Messages API through the ``anthropic`` client."""

    def __init__(self, config: LLMConfig) -> None:
        super().__init__(config)
        try:
            import anthropic
        except ImportError as exc:  # pragma: no cover - extras not installed
            raise DualtwinError("the 'anthropic' package is needed: pip install 'dualtwin[llm]'") from exc
        self._anthropic = anthropic
        http = bounded_client(anthropic.DefaultHttpxClient, reply_s=config.timeout_s, max_bytes=MAX_REPLY_BYTES)
        self._client = anthropic.Anthropic(api_key=config.api_key or NO_KEY, base_url=config.base_url,
                                           timeout=config.timeout_s, max_retries=config.max_retries, http_client=http)

    def complete(self, messages: list[Message], *, json_schema: dict[str, Any] | None = None) -> str:
        anthropic = self._anthropic
        system = "\n\n".join(m["content"] for m in messages if m["role"] == "system")
        chat = [{"role": m["role"], "content": m["content"]} for m in messages if m["role"] != "system"]
        # Recent anthropic clients dropped ``temperature`` from messages.create(); the default is used.
        kwargs: dict[str, Any] = {"model": self.config.model, "max_tokens": self.config.max_tokens, "messages": chat}
        if system:
            kwargs["system"] = system
        try:
            response = self._client.messages.create(**kwargs)
        except (anthropic.APIConnectionError, anthropic.APIStatusError) as exc:
            raise self._error(exc) from None
        except (json.JSONDecodeError, RecursionError) as exc:
            raise self._unreadable(exc) from None
        blocks = getattr(response, "content", None)
        parts = [text for block in (blocks if isinstance(blocks, list) else [])
                 if getattr(block, "type", "") == "text" and isinstance(text := getattr(block, "text", None), str)]
        if not parts:
            raise DualtwinError(f"{self.config.where}: reply has no text content")
        return self._check_size("".join(parts))


def _chat_content(response: Any) -> str | None:
    """The first choice's text of a chat completion, or None.

    The client builds its reply objects without validating them, so a broken or hostile server's ``choices``
    may be a string or hold numbers (an AttributeError, a traceback, before): every level is checked.
    """
    choices = getattr(response, "choices", None)
    if not isinstance(choices, list) or not choices:
        return None
    content = getattr(getattr(choices[0], "message", None), "content", None)
    return content if isinstance(content, str) else None


def make_llm(config: LLMConfig | None = None) -> LLMClient:
    """The client for a configuration (default: :func:`load_llm_config` from the environment)."""
    config = config or load_llm_config()
    if config.provider == "anthropic":
        return AnthropicClient(config)
    return OpenAIChatClient(config)


def with_overrides(config: LLMConfig, **changes: Any) -> LLMConfig:
    """A copy with some fields changed (e.g. shorter timeouts in tests)."""
    return replace(config, **changes)
