"""LLM providers: configuration, redaction, and failures against real loopback servers."""

from __future__ import annotations

import socket
import time
from pathlib import Path

import pytest

from dualtwin.errors import DualtwinError
from dualtwin.genai.llm import (
    MAX_REPLY_BYTES,
    AnthropicClient,
    LLMConfig,
    OpenAIChatClient,
    load_llm_config,
    make_llm,
)
from tests.support.llm_replay import Reply, replay_server

KEY = "sk-test-secret-1234"


def test_config_from_env_and_file(tmp_path: Path) -> None:
    cfg_file = tmp_path / "llm.yaml"
    cfg_file.write_text("provider: anthropic\nmodel: file-model\napi_key_env: MY_KEY\ntimeout_s: 5\n")
    cfg = load_llm_config(cfg_file, env={"MY_KEY": KEY})
    assert (cfg.provider, cfg.model, cfg.api_key, cfg.timeout_s) == ("anthropic", "file-model", KEY, 5)
    cfg = load_llm_config(cfg_file, env={"DUALTWIN_LLM_PROVIDER": "openai", "DUALTWIN_LLM_MODEL": "m2",
                                          "DUALTWIN_LLM_BASE_URL": "http://127.0.0.1:1/v1", "OPENAI_API_KEY": KEY})
    assert (cfg.provider, cfg.model, cfg.base_url, cfg.api_key) == ("openai", "m2", "http://127.0.0.1:1/v1", KEY)
    assert load_llm_config(env={"DUALTWIN_LLM_MODEL": "x", "DUALTWIN_LLM_API_KEY": "k2", "OPENAI_API_KEY": KEY}).api_key == "k2"
    with pytest.raises(DualtwinError, match="no LLM model"):
        load_llm_config(env={})
    with pytest.raises(DualtwinError, match="unknown LLM provider"):
        load_llm_config(env={"DUALTWIN_LLM_PROVIDER": "gemini", "DUALTWIN_LLM_MODEL": "x"})
    (tmp_path / "bad.yaml").write_text("model: x\ncolour: red\n")
    with pytest.raises(DualtwinError, match="unknown LLM config keys"):
        load_llm_config(tmp_path / "bad.yaml", env={})


def test_key_is_never_shown() -> None:
    cfg = LLMConfig(model="m", api_key=KEY)
    assert KEY not in repr(cfg) and KEY not in str(cfg) and "***" in repr(cfg)
    assert KEY not in repr(make_llm(cfg))
    assert cfg.redact(f"Authorization: Bearer {KEY}") == "Authorization: Bearer ***"


def test_openai_compatible_call_uses_json_mode_and_the_key() -> None:
    with replay_server([Reply('{"ok": true}')]) as (base, log):
        client = OpenAIChatClient(LLMConfig(model="local-model", base_url=base, api_key=KEY, timeout_s=5))
        assert client.complete([{"role": "user", "content": "hi"}], json_schema={"type": "object"}) == '{"ok": true}'
    assert log.paths == ["/v1/chat/completions"]
    assert log.requests[0]["model"] == "local-model"
    assert log.requests[0]["response_format"] == {"type": "json_object"}
    assert log.headers[0]["authorization"] == f"Bearer {KEY}"


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_unreachable_provider() -> None:
    port = _closed_port()
    client = OpenAIChatClient(LLMConfig(model="m", base_url=f"http://127.0.0.1:{port}/v1", api_key=KEY,
                                        timeout_s=2, max_retries=0))
    with pytest.raises(DualtwinError, match="cannot connect") as err:
        client.complete([{"role": "user", "content": "hi"}])
    assert KEY not in str(err.value)


def test_server_error_is_retried_a_bounded_number_of_times() -> None:
    with replay_server([Reply(status=500)] * 5) as (base, log):
        client = OpenAIChatClient(LLMConfig(model="m", base_url=base, api_key=KEY, timeout_s=5, max_retries=1))
        with pytest.raises(DualtwinError, match="HTTP 500"):
            client.complete([{"role": "user", "content": "hi"}])
    assert len(log.requests) == 2  # first try + 1 retry


def test_timeout() -> None:
    with replay_server([Reply("late", delay_s=1.5)] * 3) as (base, log):
        client = OpenAIChatClient(LLMConfig(model="m", base_url=base, api_key=KEY, timeout_s=0.3, max_retries=0))
        start = time.monotonic()
        with pytest.raises(DualtwinError, match="timed out"):
            client.complete([{"role": "user", "content": "hi"}])
        assert time.monotonic() - start < 1.4


def test_anthropic_protocol() -> None:
    with replay_server([Reply("hello from claude")], protocol="anthropic") as (base, log):
        client = AnthropicClient(LLMConfig(provider="anthropic", model="claude-test", base_url=base, api_key=KEY,
                                           timeout_s=5))
        text = client.complete([{"role": "system", "content": "be brief"}, {"role": "user", "content": "hi"}])
    assert text == "hello from claude"
    assert log.paths == ["/v1/messages"]
    assert log.requests[0]["system"] == "be brief"
    assert log.requests[0]["messages"] == [{"role": "user", "content": "hi"}]
    # Older anthropic clients send x-api-key, newer ones a bearer token.
    assert log.headers[0].get("x-api-key") == KEY or log.headers[0].get("authorization") == f"Bearer {KEY}"


@pytest.mark.parametrize("protocol", ["openai", "anthropic"])
@pytest.mark.parametrize(("body", "expected"), [
    (b"<html>502 Bad Gateway</html>", "the reply is not a JSON document"),
    (b'{"choices": "abc", "content": 5}', "reply has no text content"),
    (b'{"choices": [{"message": 5}], "content": [5, {"type": "text", "text": 3}]}', "reply has no text content"),
])
def test_a_malformed_reply_body_is_one_error_not_a_traceback(protocol: str, body: bytes, expected: str) -> None:
    # Found by serving hostile bodies to `dualtwin generate --from-text`: a body that is not JSON raised
    # JSONDecodeError, and `choices`/`content` of the wrong type AttributeError or TypeError (tracebacks; the
    # client libraries build reply objects without validating them).
    cls = OpenAIChatClient if protocol == "openai" else AnthropicClient
    with replay_server([Reply(raw=body)], protocol=protocol) as (base, _):
        client = cls(LLMConfig(provider=protocol, model="m", base_url=base, api_key=KEY, timeout_s=5, max_retries=0))  # type: ignore[arg-type]
        with pytest.raises(DualtwinError, match=expected):
            client.complete([{"role": "user", "content": "hi"}])


@pytest.mark.parametrize("protocol", ["openai", "anthropic"])
@pytest.mark.parametrize(("reply", "expected"), [
    (Reply(trickle_s=20), "timed out after 0.5 s"),  # a byte every 50 ms: each read is quick, the body never ends
    (Reply(raw=b" " * (MAX_REPLY_BYTES + 1)), f"reply body larger than {MAX_REPLY_BYTES} bytes"),
])
def test_a_reply_that_never_ends_or_is_too_large_is_cut_off(protocol: str, reply: Reply, expected: str) -> None:
    # Found by serving `dualtwin generate --from-text` a reply that trickles forever: the HTTP timeouts bound each
    # read, not the body, so generate waited forever (here the server gives up after 20 s, and the client's
    # error then names a lost connection, not a timeout); an endless fast reply filled the memory.
    cls = OpenAIChatClient if protocol == "openai" else AnthropicClient
    with replay_server([reply], protocol=protocol) as (base, _):
        client = cls(LLMConfig(provider=protocol, model="m", base_url=base, api_key=KEY, timeout_s=0.5,  # type: ignore[arg-type]
                               max_retries=0))
        with pytest.raises(DualtwinError, match=expected):
            client.complete([{"role": "user", "content": "hi"}])
