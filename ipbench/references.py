"""``module:attribute`` references to a user's own code: a custom sorting policy or classifier.

``ipbench eval sorting --policies random,mypkg.policies:MyPolicy`` and ``ipbench eval
perception --classifiers gp,mypkg.models:MyClassifier`` name user code the way entry points do:
the module's import path, a colon, the attribute (a class, or any callable that builds one).
:func:`load_reference` imports it and checks the protocol up front (the attribute exists, can be
called with the arguments the evaluation passes, and has the methods it calls), so that a typo
fails in a second with a message that says what is missing and how to fix it, not after the
models trained.

The evaluation runs episodes in worker processes (spawned, or Ray tasks), which import the
reference again by name. A module found through ``PYTHONPATH`` is found there too (the workers
inherit the environment). The ``ipbench`` command does not search the current folder the way
``python -m`` does; a module found only there is found after :func:`load_reference` puts the
folder on ``sys.path`` (which spawned workers copy) and on ``PYTHONPATH`` (which workers
started later, Ray's among them, read).
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = [
    "DOCS",
    "Method",
    "ReferenceLoadError",
    "check_methods",
    "is_reference",
    "load_reference",
    "split_reference",
]

DOCS = "docs/custom.md"
"""The page that describes the protocols (named in the error messages)."""


class ReferenceLoadError(ValueError):
    """A ``module:attribute`` reference that cannot be used; the message says why and how to fix
    it."""


@dataclass(frozen=True)
class Method:
    """A method the evaluation calls: ``name`` with ``args`` positional arguments besides
    ``self``; ``shown`` is how the messages write it (``"act(observation, info)"``)."""

    name: str
    args: int
    shown: str


def is_reference(name: str) -> bool:
    """Whether ``name`` is a ``module:attribute`` reference (built-in names hold no colon)."""
    return ":" in name


def split_reference(
    ref: str, what: str = "method", example: str = "mypkg.module:MyClass"
) -> tuple[str, str]:
    """``"mypkg.policies:MyPolicy"`` -> ``("mypkg.policies", "MyPolicy")``, checking the form
    only (nothing is imported). ``what`` names the kind and ``example`` shows one in the
    message."""
    module, _, attribute = ref.partition(":")
    parts = [*module.split("."), *attribute.split(".")]
    if not module or not attribute or not all(p.isidentifier() for p in parts):
        raise ReferenceLoadError(
            f"{ref!r} is not a {what} reference; write module:attribute, the module's import "
            f"path and the class in it, e.g. {example} (see {DOCS})"
        )
    return module, attribute


def _on_path(module: str) -> None:
    """Put the current folder on ``sys.path`` and ``PYTHONPATH`` when ``module`` is found only
    there (module docstring)."""
    here, top = os.getcwd(), module.partition(".")[0]
    if here in sys.path or "" in sys.path or importlib.util.find_spec(top) is not None:
        return
    sys.path.append(here)
    importlib.invalidate_caches()
    if importlib.util.find_spec(top) is None:
        sys.path.remove(here)
        return
    paths = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    os.environ["PYTHONPATH"] = os.pathsep.join([*paths, here])


def _import(module: str, ref: str, what: str):
    """Import ``module`` (found in the current folder too: :func:`_on_path`)."""
    try:
        _on_path(module)
        return importlib.import_module(module)
    except ModuleNotFoundError as err:
        missing = err.name or ""
        if module == missing or module.startswith(missing + "."):
            raise ReferenceLoadError(
                f"cannot import module {module!r} of the {what} {ref!r} ({err}); run ipbench "
                "from the folder that holds it, add that folder to PYTHONPATH, or install the "
                f"package (see {DOCS})"
            ) from err
        raise ReferenceLoadError(
            f"importing {module!r} of the {what} {ref!r} failed: {err} (a module it imports is "
            "missing: install it)"
        ) from err
    except Exception as err:  # the user's module raised while it was imported
        raise ReferenceLoadError(
            f"importing {module!r} of the {what} {ref!r} failed: {type(err).__name__}: {err}"
        ) from err


def _article(noun: str) -> str:
    return f"{'an' if noun[:1].lower() in 'aeiou' else 'a'} {noun}"


def _accepts(function, args: int) -> bool:
    """Whether ``function`` can be called with ``args`` positional arguments (True when its
    signature cannot be read, e.g. a built-in)."""
    try:
        inspect.signature(function).bind(*([None] * args))
    except TypeError:
        return False
    except ValueError:
        return True
    return True


def check_methods(
    target: object, ref: str, what: str, methods: Sequence[Method], needs: str
) -> None:
    """Check that ``target`` (a class or an instance) has each of ``methods``, callable with
    its arguments; ``needs`` ends the message (``"a sorting policy needs ..."``)."""
    for method in methods:
        found = inspect.getattr_static(target, method.name, None)
        if found is None or not callable(getattr(target, method.name, None)):
            raise ReferenceLoadError(f"{ref} has no method {method.shown}; {needs} (see {DOCS})")
        # a plain function in a class is called with self first
        bound = isinstance(target, type) and inspect.isfunction(found)
        function = found if bound else getattr(target, method.name)
        if not _accepts(function, method.args + bound):
            raise ReferenceLoadError(
                f"{ref}: {method.name} cannot be called as {method.shown}; {needs} (see {DOCS})"
            )


def load_reference(
    ref: str,
    what: str,
    construct: Sequence[str],
    methods: Sequence[Method],
    needs: str,
    example: str = "mypkg.module:MyClass",
):
    """The attribute ``ref`` names (``module:attribute``), checked: the module imports, the
    attribute exists, is callable with ``construct`` (the names of the positional arguments
    the evaluation builds it with) and, when it is a class, has ``methods``. ``what`` (e.g.
    ``"policy"``), ``needs`` and ``example`` (a reference of the kind) go into the messages.

    Raises
    ------
    ReferenceLoadError
        saying what is missing and how to fix it.
    """
    module, attribute = split_reference(ref, what, example)
    target = _import(module, ref, what)
    for i, part in enumerate(attribute.split(".")):
        if not hasattr(target, part):
            owner = ".".join([module, *attribute.split(".")[:i]])
            public = sorted(n for n in dir(target) if not n.startswith("_"))
            classes = [n for n in public if inspect.isclass(getattr(target, n))]
            public = classes or public
            shown = ", ".join(public[:12]) + (", ..." if len(public) > 12 else "")
            raise ReferenceLoadError(
                f"{owner} has no attribute {part!r} (it has: {shown or 'nothing public'}); "
                f"check the name after the colon in {ref!r} (see {DOCS})"
            )
        target = getattr(target, part)
    call = f"{attribute}({', '.join(construct)})"
    if not callable(target):
        raise ReferenceLoadError(
            f"{ref} is not a class (it is {_article(type(target).__name__)}); the evaluation "
            f"builds the {what} as {call} (see {DOCS})"
        )
    if not _accepts(target, len(construct)):
        raise ReferenceLoadError(
            f"{ref} cannot be called as {call}; the evaluation builds the {what} so: make "
            f"{'__init__' if isinstance(target, type) else 'it'} take {', '.join(construct)} "
            f"(see {DOCS})"
        )
    if isinstance(target, type):
        check_methods(target, ref, what, methods, needs)
    return target
