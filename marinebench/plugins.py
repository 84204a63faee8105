"""Classes of your own named by a config (``source: file.py:Class`` or ``package.module:Class``): a custom
observer (``observers/custom.py``) or controller (``controllers/spec.py``).

A ``.py`` source is relative to the experiment file that names it (:func:`resolve_source`, applied when the file
is read) and re-imported when it changes; a module source is imported as usual. Every failure is a ValueError
with a one-line reason, so config validation reports it with the file and key.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import sys
import traceback
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from marinebench.errors import ProtocolError, UserCodeError

_LOADED: dict[str, tuple[float, type]] = {}


def split_source(source: str) -> tuple[str, str]:
    """``(file or module, class name)``."""
    where, _, name = source.rpartition(":")
    if not where or not name.isidentifier():
        raise ValueError(f"source '{source}': expected file.py:ClassName or package.module:ClassName")
    return where, name


def _module(where: str):
    if not where.endswith(".py"):
        try:
            return importlib.import_module(where)
        except Exception as exc:  # noqa: BLE001 - the user's module: any error is a config error naming it
            raise ValueError(f"cannot import module '{where}' ({type(exc).__name__}: {exc})") from None
    path = Path(where)
    module_name = "marinebench_user_" + hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:12]
    spec = importlib.util.spec_from_file_location(module_name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module  # dataclasses and pickling look the module up by name
    try:
        spec.loader.exec_module(module)
    except Exception as exc:  # noqa: BLE001 - as above
        del sys.modules[module_name]
        raise ValueError(f"{where}: cannot import ({type(exc).__name__}: {exc})") from None
    return module


def user_class(source: str, members: Iterable[str]) -> type:
    """The class ``source`` names, with every one of ``members`` (attributes or methods); cached until a
    ``.py`` source changes."""
    where, name = split_source(source)
    if where.endswith(".py") and not Path(where).is_file():
        raise ValueError(f"source file not found: {where}")
    mtime = Path(where).stat().st_mtime if where.endswith(".py") else 0.0
    if source in _LOADED and _LOADED[source][0] == mtime:
        return _LOADED[source][1]
    cls = getattr(_module(where), name, None)
    if not isinstance(cls, type):
        raise ValueError(f"{where} has no class '{name}'")  # noqa: TRY004 - pydantic reports ValueErrors
    missing = [m for m in members if not hasattr(cls, m)]
    if missing:
        raise ValueError(f"{name} ({where}) lacks {', '.join(missing)}")
    _LOADED[source] = (mtime, cls)
    return cls


def user_code_error(exc: BaseException, sources: Iterable[str]) -> UserCodeError | None:
    """``exc``, raised while the runs were simulated, as one line naming where in a class of your own (one of
    ``sources``) it was raised: its file, line and member (None when no frame of its traceback is in one of their
    files, e.g. an engine error), or, for a :class:`ProtocolError` (an answer outside the protocol), what was wrong.
    The class was checked at validation; this is what it did later."""
    if isinstance(exc, ProtocolError):
        return UserCodeError(f"{exc} (a class of your own, while the runs were simulated)")
    files = set()
    for source in sources:
        where, _ = split_source(source)
        module = None if where.endswith(".py") else sys.modules.get(where)
        path = where if module is None else getattr(module, "__file__", None)
        if path:
            files.add(Path(path).resolve())
    frames = [f for f in traceback.extract_tb(exc.__traceback__) if Path(f.filename).resolve() in files]
    if not frames:
        return None
    last = frames[-1]
    return UserCodeError(f"{last.filename}, line {last.lineno}, in {last.name}: {type(exc).__name__}: {exc} (a class "
                         "of your own, while the runs were simulated)")


def source_digest(source: str) -> str | None:
    """SHA-256 of the file that defines the class: the ``.py`` source, or a module source's own file (its
    ``__spec__.origin``, e.g. ``site-packages/lab/observers.py``), so that the manifest names the code that ran and
    ``run --resume`` and a sweep's finished batches go stale when it is edited. Like a ``.py`` source, only that one
    file is hashed, not what it imports. None for a module without a file of its own (a namespace package)."""
    where, _ = split_source(source)
    if not where.endswith(".py"):
        where = _module_file(where)
        if where is None:
            return None
    return hashlib.sha256(Path(where).read_bytes()).hexdigest()


def _module_file(name: str) -> str | None:
    """The file a module is loaded from (it has been imported when its class was checked), or None."""
    try:
        spec = importlib.util.find_spec(name)
    except (ImportError, ValueError):
        return None
    origin = getattr(spec, "origin", None)
    return origin if spec is not None and spec.has_location and origin and Path(origin).is_file() else None


def resolve_source(source: Any, base: Path) -> Any:
    """A relative ``file.py:Class`` made absolute against ``base`` (the experiment file's folder)."""
    if not isinstance(source, str) or ":" not in source:
        return source
    where, _, name = source.rpartition(":")
    if not where.endswith(".py") or Path(where).is_absolute():
        return source
    return f"{(base / where).resolve()}:{name}"
