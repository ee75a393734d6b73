"""``cma`` without its optional imports.

``import cma`` imports ``matplotlib.pyplot`` (for ``cma.plot``) and ``scipy.stats`` (Kendall's tau, for its
surrogate fitness models), which cost about two CPU-seconds, more than a small fit's whole optimisation, on
every ``dualtwin align``. Alignment uses neither, so cma is imported with the modules it would load for them
marked unavailable: cma then takes its own fallbacks (no plotting; its pure-Python Kendall tau, which only
the surrogate models call), and its warning about the missing plotting is silenced. Modules a program
imported before are left alone, and cma uses them as before. CMA-ES itself (sampling, adaptation) touches
none of them: fits are unchanged.
"""

from __future__ import annotations

import sys
import warnings

_OPTIONAL = ("matplotlib", "matplotlib.pyplot", "scipy.stats")

_blocked = [name for name in _OPTIONAL if name not in sys.modules]
for _name in _blocked:
    sys.modules[_name] = None  # type: ignore[assignment]  # an import of it raises ImportError
try:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import cma
finally:
    for _name in _blocked:
        del sys.modules[_name]

__all__ = ["cma"]
