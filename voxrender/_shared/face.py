"""The face of a package: the names its users need, each imported from its module on first use.

A package's ``__init__`` says::

    _FACE = {"View": "view", "PRESETS": "view"}
    __all__ = list(_FACE)
    __getattr__, __dir__ = face(__name__, _FACE)

so that importing the package imports none of its modules (``voxrender --help`` stays fast, and a module of a
lower layer can import a sibling module without running the package's other imports), as scikit-image's
``lazy_loader`` does.
"""

from __future__ import annotations

import importlib
import sys


def face(package, names):
    """``__getattr__`` and ``__dir__`` for ``package`` (its ``__name__``): ``names`` maps each name of its face to
    the module (relative to the package) that defines it.  A name of the face is never that of one of the
    package's modules: ``from package import module`` would find the name instead.
    """
    clashes = [name for name, module in names.items() if name == module]
    assert not clashes, f"{package}'s face hides its modules {clashes}"
    def __getattr__(name):
        if name not in names:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{names[name]}"), name)
        setattr(sys.modules[package], name, value)      # the next look-up finds it without coming here
        return value

    def __dir__():
        return sorted({*vars(sys.modules[package]), *names})

    return __getattr__, __dir__
