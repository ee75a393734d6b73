"""Whether a dotted ``dualtwin...`` name in prose (docs pages, docstrings) still names something."""

from __future__ import annotations

import importlib
import re

#: A dotted dualtwin name. Not names: schema ids (a trailing "/": ``dualtwin.knobs/1``) and string literals
#: (a leading quote: the MJCF text element ``"dualtwin.knobs"``).
DOTTED = re.compile(r"(?<![\"'\w.])dualtwin(?:\.[A-Za-z_]\w*)+(?![\w/])")


def resolves(dotted: str) -> bool:
    """``dualtwin.a.b.Name`` names an importable module, or an attribute of the longest importable prefix."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj: object = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for attr in parts[i:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


def dotted_names(text: str) -> set[str]:
    """The dotted dualtwin names in ``text``, and ``module.name`` for each ``from dualtwin... import name``."""
    found = {d.rstrip(".") for d in DOTTED.findall(text)}
    for module, names in re.findall(r"from (dualtwin(?:\.\w+)*) import ([\w, ]+)", text):
        found |= {f"{module}.{n.split()[0]}" for n in names.split(",") if n.strip()}
    return found
