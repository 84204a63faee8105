"""Classes of your own named by a config (``source: file.py:Class`` or ``package.module:Class``): a custom
observer (``observers/custom.py``) or controller (``controllers/spec.py``).

A ``.py`` source is relative to the experiment file that names it (:func:`resolve_source`, applied when the file
is read) and imports the files beside it as ``python file.py`` would (:func:`_module`: its folder is first on
``sys.path`` while it runs, last after); a module source is imported as usual. Either is imported again, with the
files of your own code it imports (:func:`source_files`), once one of those files changes, so a long-lived process
(a notebook calling ``marinebench.run`` again) runs the code on disk, the code its manifest hashes. Every failure is
a ValueError with a one-line reason, so config validation reports it with the file and key.
"""

from __future__ import annotations

import ast
import hashlib
import importlib
import importlib.util
import sys
import sysconfig
import traceback
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from marinebench.errors import ProtocolError, UserCodeError

#: source -> (its files, their stamps when it was imported, the class).
_LOADED: dict[str, tuple[list[Path], tuple, type]] = {}
#: The folders of the ``.py`` sources imported in this process (each is on ``sys.path``, last).
_FOLDERS: set[Path] = set()


def split_source(source: str) -> tuple[str, str]:
    """``(file or module, class name)``."""
    where, _, name = source.rpartition(":")
    if not where or not name.isidentifier():
        raise ValueError(f"source '{source}': expected file.py:ClassName or package.module:ClassName")
    return where, name


def _module_name(where: str) -> str:
    """The name the module of ``where`` (a module, or a ``.py`` file: a name of its own) has in ``sys.modules``."""
    if not where.endswith(".py"):
        return where
    return "marinebench_user_" + hashlib.sha1(str(Path(where).resolve()).encode()).hexdigest()[:12]


def _module(where: str):
    """The module ``where`` names: imported, or the one in ``sys.modules`` (which :func:`user_class` has dropped
    unless it is current), so a file's classes come from one execution of it, as a module's do."""
    if not where.endswith(".py"):
        try:
            return importlib.import_module(where)
        except Exception as exc:  # noqa: BLE001 - the user's module: any error is a config error naming it
            raise ValueError(f"cannot import module '{where}' ({type(exc).__name__}: {exc})") from None
    module_name = _module_name(where)
    if module_name in sys.modules:
        return sys.modules[module_name]
    path = Path(where).resolve()
    spec = importlib.util.spec_from_file_location(module_name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module  # dataclasses and pickling look the module up by name
    folder = str(path.parent)
    _forget_helpers_of_other_folders(path)
    _FOLDERS.add(path.parent)
    sys.path.insert(0, folder)  # its imports find the files beside it first, as with `python file.py`
    try:
        spec.loader.exec_module(module)
    except Exception as exc:  # noqa: BLE001 - as above
        del sys.modules[module_name]
        raise ValueError(f"{where}: cannot import ({type(exc).__name__}: {exc})") from None
    finally:  # then last, so that an import at run time finds them too, but never shadows an installed module
        if folder in sys.path:
            sys.path.remove(folder)
        if folder not in sys.path:
            sys.path.append(folder)
    return module


def _forget_helpers_of_other_folders(path: Path) -> None:
    """Drop from ``sys.modules`` each module the ``.py`` source ``path`` imports by a name a file beside it has
    (``gains`` for ``gains.py`` or a package ``gains/``) that was loaded from the folder of another ``.py`` source (a
    helper of the same name beside a source run earlier in this process), so that it imports its own. A module
    loaded from anywhere else (an installed one) is left alone: the import finds that one, as it did before."""
    folder = path.parent
    for name in _imported_names(path, None):
        module = sys.modules.get(name)
        if "." in name or module is None or _file_in(folder, name) is None:
            continue
        file = getattr(module, "__file__", None)
        where = Path(file).resolve() if isinstance(file, str) else None
        if where is not None and any(where.is_relative_to(other) for other in _FOLDERS - {folder}):
            for other in [m for m in sys.modules if m == name or m.startswith(f"{name}.")]:
                del sys.modules[other]


def user_class(source: str, members: Iterable[str]) -> type:
    """The class ``source`` names, with every one of ``members`` (attributes or methods); cached until one of its
    :func:`source_files` changes, then imported again with them (their modules are dropped from ``sys.modules`` first,
    so an edited helper is run again too, not taken from the modules Python keeps). A module source that was imported
    before its first use here (by you, say) is imported again, with its files, the same way. Classes of one module or
    file, with its files unchanged, come from one import of it."""
    where, name = split_source(source)
    if where.endswith(".py") and not Path(where).is_file():
        raise ValueError(f"source file not found: {where}")
    cached = _LOADED.get(source)
    if cached is not None:
        if _stamps(cached[0]) == cached[1]:
            return cached[2]
        del _LOADED[source]
    key = _module_name(where)
    if not _current(key):  # else another class of it was imported since its files last changed: that import serves
        if cached is not None:  # edited since
            _forget(cached[0])
        elif key in sys.modules:  # imported by you (in a notebook), or by a class of it before an edit
            _forget(source_files(source))
    cls = getattr(_module(where), name, None)
    if not isinstance(cls, type):
        raise ValueError(f"{where} has no class '{name}'")  # noqa: TRY004 - pydantic reports ValueErrors
    missing = [m for m in members if not hasattr(cls, m)]
    if missing:
        raise ValueError(f"{name} ({where}) lacks {', '.join(missing)}")
    files = source_files(source)
    _LOADED[source] = (files, _stamps(files), cls)
    return cls


def _current(key: str) -> bool:
    """Whether the module named ``key`` in ``sys.modules`` was imported here, for another class of it, whose files
    are unchanged since."""
    return any(_module_name(split_source(other)[0]) == key and _stamps(files) == stamps
               for other, (files, stamps, _) in _LOADED.items())


def _stamps(files: list[Path]) -> tuple:
    """(modification time in ns, size) of each file; None for one that is gone."""
    out = []
    for path in files:
        try:
            stat = path.stat()
        except OSError:
            out.append(None)
        else:
            out.append((stat.st_mtime_ns, stat.st_size))
    return tuple(out)


def _forget(files: list[Path]) -> None:
    """Drop the modules loaded from ``files`` from ``sys.modules``, so that importing them runs their code again."""
    stale, names = set(files), {path.name for path in files}
    for name, module in list(sys.modules.items()):
        file = getattr(module, "__file__", None)  # resolved only when the file's name matches: ~2000 modules
        if isinstance(file, str) and Path(file).name in names and Path(file).resolve() in stale:
            del sys.modules[name]
    importlib.invalidate_caches()  # a file added since (a new helper) is found


def user_code_error(exc: BaseException, sources: Iterable[str]) -> UserCodeError | None:
    """``exc``, raised while the runs were simulated, as one line naming where in a class of your own (one of
    ``sources``) it was raised: its file, line and member, or those of a file of your own it imports (None when no
    frame of its traceback is in one of their :func:`source_files`, e.g. an engine error), or, for a
    :class:`ProtocolError` (an answer outside the protocol), what was wrong. The class was checked at validation;
    this is what it did later."""
    if isinstance(exc, ProtocolError):
        return UserCodeError(f"{exc} (a class of your own, while the runs were simulated)")
    files = {path for source in sources for path in source_files(source)}
    frames = [f for f in traceback.extract_tb(exc.__traceback__) if Path(f.filename).resolve() in files]
    if not frames:
        return None
    last = frames[-1]
    return UserCodeError(f"{last.filename}, line {last.lineno}, in {last.name}: {type(exc).__name__}: {exc} (a class "
                         "of your own, while the runs were simulated)")


def source_record(source: str) -> tuple[str | None, dict[str, str]]:
    """(SHA-256 of the file that defines the class, SHA-256 of each file of your own code it imports), from one walk
    of :func:`source_files`. The first is of the ``.py`` source or of a module source's own file (e.g.
    ``site-packages/lab/observers.py``), None for a module without a file (a namespace package); the imported files
    are named relative to their package's parent folder (``lab/gains.py``) or to the source's folder
    (``helpers.py``)."""
    files = source_files(source)
    if not files:
        return None, {}
    root, _ = _own_code_root(source, files[0])
    return file_digest(files[0]), {path.relative_to(root).as_posix(): file_digest(path) for path in files[1:]}


def file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def source_files(source: str) -> list[Path]:
    """The files a class of your own is computed by: the one that defines it, then (sorted) every file of your own
    code it imports, directly or through one another, so that the manifest names the code that ran and ``run
    --resume`` and a sweep's finished batches go stale when any of them is edited.

    Your own code is what lies in the class's top-level package (``lab/`` for ``lab.observers.eso:Class``), or,
    for a ``.py`` source or a module outside any package, in its folder and below, less the interpreter's library
    and installed packages (a ``site-packages`` or ``dist-packages`` folder). marinebench itself is never followed:
    its code is in every manifest's ``source_digest``. The imports are read from the files (``ast``), not run, so
    one inside a function or under a condition counts as well; a name that is not found (or would import a package
    that its class did not) is skipped. Empty for a module without a file of its own (a namespace package)."""
    where, _ = split_source(source)
    first = Path(where).resolve() if where.endswith(".py") else _module_file(where, may_import=True)
    if first is None:
        return []
    _, follows = _own_code_root(source, first)
    beside = first.parent if where.endswith(".py") else None  # first on sys.path while it was imported
    found, todo = {first}, [(first, None if beside else _package_of(where, first))]
    while todo:
        path, package = todo.pop()
        for name in _imported_names(path, package):
            file = (beside and _file_in(beside, name)) or _module_file(name)
            if file is not None and file not in found and follows(file):
                found.add(file)
                todo.append((file, _package_of(name, file)))
    return [first, *sorted(found - {first})]


#: Folders of installed packages (the environment's, the user's, a system's), never your own code.
INSTALLED = frozenset({"site-packages", "dist-packages"})


def _own_code_root(source: str, first: Path):
    """(the folder imported files are named relative to, whether a file is your own code) for ``source``."""
    where, _ = split_source(source)
    top = None if where.endswith(".py") else sys.modules.get(where.partition(".")[0])
    locations = list(getattr(getattr(top, "__spec__", None), "submodule_search_locations", None) or [])
    if len(locations) == 1:  # a regular package: all of it is yours
        package = Path(locations[0]).resolve()
        return package.parent, lambda file: file.is_relative_to(package)
    folder = first.parent
    others = [Path(sysconfig.get_path(key)).resolve() for key in ("stdlib", "platstdlib")]
    others.append(Path(__file__).resolve().parent)  # marinebench
    return folder, lambda file: (file.is_relative_to(folder) and not INSTALLED.intersection(file.parts)
                                 and not any(file.is_relative_to(o) for o in others))


def _package_of(name: str, file: Path) -> str:
    """The package a module's relative imports start from."""
    return name if file.name == "__init__.py" else name.rpartition(".")[0]


def _imported_names(path: Path, package: str | None) -> list[str]:
    """Every module name an import statement of the file names (with its parent packages, and ``from a import b``'s
    ``a.b``, which may be a module), relative imports resolved against ``package`` (skipped without one)."""
    try:
        tree = ast.parse(path.read_bytes(), filename=str(path))
    except (SyntaxError, ValueError, OSError):
        return []
    names = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                if not package:
                    continue
                try:
                    base = importlib.util.resolve_name("." * node.level + base, package)
                except (ImportError, ValueError):
                    continue
            names += [base, *(f"{base}.{alias.name}" for alias in node.names if alias.name != "*")]
    parts = (name.split(".") for name in names if name)
    return list(dict.fromkeys(".".join(p[: i + 1]) for p in parts for i in range(len(p))))


def _file_in(folder: Path, name: str) -> Path | None:
    """The file of module ``name`` in ``folder`` (``a/b.py`` or ``a/b/__init__.py`` for ``a.b``), or None."""
    base = folder.joinpath(*name.split("."))
    for file in (base.parent / f"{base.name}.py", base / "__init__.py"):
        if file.is_file():
            return file.resolve()
    return None


def _module_file(name: str, may_import: bool = False) -> Path | None:
    """The file module ``name`` is (or would be) loaded from, or None: from ``sys.modules`` if it was imported, else
    looked up, which imports its parent packages if ``may_import`` (a class's own module, imported anyway) and
    otherwise is not done when they are not imported yet (an import the class's own did not make)."""
    module = sys.modules.get(name)
    spec = getattr(module, "__spec__", None)
    if module is None:
        parent = name.rpartition(".")[0]
        if parent and parent not in sys.modules and not may_import:
            return None
        try:
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError):
            return None
    origin = getattr(spec, "origin", None)
    if spec is None or not spec.has_location or not origin or not Path(origin).is_file():
        return None
    return Path(origin).resolve()


def resolve_source(source: Any, base: Path) -> Any:
    """A relative ``file.py:Class`` made absolute against ``base`` (the experiment file's folder)."""
    if not isinstance(source, str) or ":" not in source:
        return source
    where, _, name = source.rpartition(":")
    if not where.endswith(".py") or Path(where).is_absolute():
        return source
    return f"{(base / where).resolve()}:{name}"
