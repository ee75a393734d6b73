"""Tokenizer for Webots R2023b ``.wbt`` and ``.proto`` text, and the one error type of the parser.

Every error is a :class:`WebotsSyntaxError` whose message reads ``file:line:col: expected X, found Y``.
The tokenizer is lazy (:class:`Lexer`) because the PROTO parser must stop before a template body;
:func:`tokenize` runs it to the end. The parser itself is :mod:`dualtwin.webots.parser`.
"""

from __future__ import annotations

import bisect
import re
from dataclasses import dataclass
from typing import Any

from dualtwin.errors import DualtwinError
from dualtwin.webots.nodes import SourceLocation

__all__ = ["Lexer", "SourceText", "Token", "WebotsSyntaxError", "clip", "describe_token", "tokenize"]

_NONFINITE = {"inf": float("inf"), "+inf": float("inf"), "-inf": float("-inf"), "nan": float("nan")}
_NONFINITE.update({"Infinity": float("inf"), "+Infinity": float("inf"), "-Infinity": float("-inf")})
_NONFINITE["NaN"] = float("nan")

# Possessive quantifiers: a plain repeated group (`(?:...|...)*`) keeps a backtracking entry per iteration, so
# one long string or run of comment lines in a world (or written by a template) took gigabytes to tokenize (a
# 30 MB name: 3.6 GB; 6 MB of '#' lines: 1.1 GB). Neither pattern ever needs to give characters back.
_WS = re.compile(r"(?:[ \t\r\n,]++|#[^\n]*+)++")
_WORD = re.compile(r'[^ \t\r\n,\[\]{}"#]+')
_STRING = re.compile(r'"(?:[^"\\]++|\\.)*+"', re.S)
_NUMBER = re.compile(r"[+-]?(?:0[xX][0-9a-fA-F]+|(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)")
_INT = re.compile(r"[+-]?(?:0[xX][0-9a-fA-F]+|\d+)")
# VRML97's identifier rule, which Webots' tokenizer follows: any character above 0x20 except
# " # ' , . [ \ ] { } and DEL; the first one also not a digit, '+' or '-'. So a backtick or a non-ASCII
# letter is a valid DEF name, a dot is not (getFromDef uses it to scope into nested DEFs).
_IDENT = re.compile(r"[^\x00-\x20\"#',.\[\\\]{}\x7f0-9+\-][^\x00-\x20\"#',.\[\\\]{}\x7f]*")
_ESCAPE = re.compile(r'\\(["\\])')


class WebotsSyntaxError(DualtwinError):
    """A malformed world or PROTO file; the message is ``file:line:col: expected X, found Y``."""

    def __init__(self, location: SourceLocation, expected: str, found: str) -> None:
        self.location = location
        self.expected = expected
        self.found = found
        super().__init__(f"{location}: expected {expected}, found {found}")


# --------------------------------------------------------------------------------------------
# tokens


@dataclass(frozen=True, slots=True)
class Token:
    """``kind`` is one of ``ident number string { } [ ] eof``; ``value`` holds the decoded value."""

    kind: str
    text: str
    start: int
    end: int
    value: Any = None


class SourceText:
    """Text plus line index: turns offsets into ``SourceLocation``."""

    def __init__(self, text: str, path: str) -> None:
        self.text = text
        self.path = path
        self._line_starts = [0] + [m.end() for m in re.finditer("\n", text)]

    def loc(self, offset: int) -> SourceLocation:
        line = bisect.bisect_right(self._line_starts, offset)
        return SourceLocation(self.path, line, offset - self._line_starts[line - 1] + 1)

    def error(self, offset: int, expected: str, found: str) -> WebotsSyntaxError:
        return WebotsSyntaxError(self.loc(offset), expected, found)


def clip(text: str, limit: int = 40) -> str:
    return text if len(text) <= limit else text[: limit - 3] + "..."


def describe_token(tok: Token) -> str:
    """Human description of a token for the ``found`` part of an error."""
    if tok.kind == "eof":
        return "end of file"
    if tok.kind == "string":
        return f"string {clip(tok.text)}"
    if tok.kind == "number":
        return f"number {clip(tok.text)}"
    if tok.kind == "ident":
        return f"'{clip(tok.text)}'"
    return f"'{tok.text}'"


def _number_value(text: str) -> int | float:
    if text in _NONFINITE:
        return _NONFINITE[text]
    if _INT.fullmatch(text):
        sign = -1 if text.startswith("-") else 1
        digits = text.lstrip("+-")
        try:
            if digits[:2] in ("0x", "0X"):
                return sign * int(digits[2:], 16)
            return sign * int(digits)
        except ValueError:  # beyond Python's int-from-str digit limit: only a float can hold it
            return float(text)
    return float(text)


class Lexer:
    """Lazy tokenizer: the PROTO parser stops before a template body it must not tokenize."""

    def __init__(self, src: SourceText, start: int = 0, end: int | None = None) -> None:
        self.src = src
        self.text = src.text
        self.pos = start
        self.limit = len(self.text) if end is None else end
        self._buf: list[Token] = []

    def _scan(self) -> Token:
        text, pos = self.text, self.pos
        m = _WS.match(text, pos, self.limit)
        if m:
            pos = m.end()
        if pos >= self.limit:
            self.pos = pos
            return Token("eof", "", pos, pos)
        ch = text[pos]
        if ch in "{}[]":
            self.pos = pos + 1
            return Token(ch, ch, pos, pos + 1)
        if ch == '"':
            m = _STRING.match(text, pos, self.limit)
            if not m:
                raise self.src.error(pos, "a closing '\"' for this string", "end of file")
            self.pos = m.end()
            raw = m.group()
            return Token("string", raw, pos, m.end(), _ESCAPE.sub(r"\1", raw[1:-1]))
        m = _WORD.match(text, pos, self.limit)
        assert m is not None  # every other character starts a word
        word = m.group()
        self.pos = m.end()
        if _NUMBER.fullmatch(word):
            return Token("number", word, pos, m.end(), _number_value(word))
        if word in _NONFINITE:
            return Token("number", word, pos, m.end(), _NONFINITE[word])
        if word.startswith(("%<", "%{")):  # would pass as an identifier: say what it is
            found = f"template code '{clip(word, 10)}' outside a procedural PROTO body"
            raise self.src.error(pos, "a name, number, string or one of { } [ ]", found)
        if _IDENT.fullmatch(word):
            return Token("ident", word, pos, m.end())
        found = f"'{clip(word)}'"
        raise self.src.error(pos, "a name, number, string or one of { } [ ]", found)

    def peek(self, k: int = 0) -> Token:
        while len(self._buf) <= k:
            if self._buf and self._buf[-1].kind == "eof":
                return self._buf[-1]
            self._buf.append(self._scan())
        return self._buf[k]

    def next(self) -> Token:
        tok = self.peek()
        if tok.kind != "eof":
            self._buf.pop(0)
        return tok

    def resume_offset(self) -> int:
        """Offset of the next unread character (start of the next buffered token, if any)."""
        return self._buf[0].start if self._buf else self.pos


def tokenize(text: str, path: str = "<string>") -> list[Token]:
    """All tokens of ``text`` (comments, whitespace and commas dropped), ending with ``eof``."""
    lexer = Lexer(SourceText(text, path))
    tokens = []
    while True:
        tok = lexer.next()
        tokens.append(tok)
        if tok.kind == "eof":
            return tokens
