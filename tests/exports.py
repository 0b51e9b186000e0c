"""A shared test helper: a module's ``__all__`` names exactly its public definitions."""

from __future__ import annotations

import importlib
import inspect


def assert_exports(name: str) -> None:
    """Every name in ``name``'s ``__all__`` exists, and every public class or function defined
    in the module is in it."""
    module = importlib.import_module(name)
    assert all(hasattr(module, n) for n in module.__all__), name
    defined = {
        n
        for n, v in vars(module).items()
        if not n.startswith("_")
        and (inspect.isclass(v) or inspect.isfunction(v))
        and v.__module__ == name
    }
    assert defined <= set(module.__all__), defined - set(module.__all__)
