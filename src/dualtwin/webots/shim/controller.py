"""Stand-in for Webots' ``controller`` Python module, for controllers run as threads of this process.

:func:`dualtwin.webots.runner.run_world` with ``isolation="threads"`` (the benchmark's baseline) puts this
directory first on ``sys.path`` so unchanged Webots scripts doing ``from controller import Robot, Motor, ...``
get the Webots-twin API, bound to the runner's current simulation. Every name the API exports is re-exported,
so a class added to :mod:`dualtwin.webots.controller` needs no change here. Controllers run as processes (the
default) get a generated module instead (:mod:`dualtwin.webots.controller_process`).
"""

from __future__ import annotations

from dualtwin.webots import controller as _api

__all__ = list(_api.__all__)
globals().update({name: getattr(_api, name) for name in __all__})
