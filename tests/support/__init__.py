"""Helpers shared by the tests; test modules (conftest.py included) import from here, never from each other
(guarded by ``tests/test_layout.py``). Nothing here is collected as a test.

* ``fake_twin``: :class:`~tests.support.fake_twin.FakeTwin`, a pure-numpy twin of damped springs, and its robot;
* ``rundirs``: fabricated suite-run folders (manifest + TSV logs), ensembles included;
* ``llm_replay``: loopback servers speaking the OpenAI and Anthropic APIs with scripted replies;
* ``suites``: the paper's published suite, byte for byte;
* ``webots_scene``: hand-built Webots scene trees for physics tests;
* ``images``: seeded camera frames;
* ``mesh_worlds``: STL/OBJ files of boxes and the project folder of a world that reads them;
* ``converted_twins``: a world converted, with both twins built from its binding (the converter's fidelity tests);
* ``align_runs``, ``rl_runs``, ``servers``, ``sync_helpers``: what one test directory's modules share.
"""
