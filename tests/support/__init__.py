"""Helpers shared by the tests: fabricated run folders, a loopback LLM replay server, the paper's suite text
and :class:`~tests.support.fake_twin.FakeTwin`. Test modules import from here, never from each other (guarded
by ``tests/test_layout.py``); nothing in this package is collected as a test."""
