"""Atomic result directories: everything is written to a temporary sibling, then swapped into place.

An interrupted or failed run leaves the previous results untouched and no half-written directory. On Linux the
swap is one system call (:func:`_exchange`); elsewhere the previous folder steps aside just before the rename.
The temporary siblings are named after the host and process writing them, so that the next write of the same
folder removes those a killed process (SIGKILL, a power cut) could not (:func:`_remove_orphans`).
"""

from __future__ import annotations

import glob
import json
import os
import platform
import shlex
import shutil
import socket
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path

from marinebench.provenance import package_digest

PACKAGES = ("marinebench", "numpy", "scipy", "cvxpy", "clarabel", "pydantic", "pandas", "matplotlib", "typer", "pyyaml")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def writable_folder(folder: Path, option: str = "--out") -> None:
    """Create ``folder`` (results go below it) and check a file can be made there, before any simulation: an
    output location that cannot be written fails at once in one line naming ``option``, not after the runs."""
    from marinebench.errors import ConfigError

    if Path(folder).exists() and not Path(folder).is_dir():
        raise ConfigError(option, "", f"{folder}: a file, not a folder")
    try:
        Path(folder).mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        raise ConfigError(option, "", f"{folder}: cannot write results there ({exc.strerror or exc})") from None


@contextmanager
def output_folder(folder: Path, option: str = "--out") -> Iterator[None]:
    """:func:`writable_folder` for the block that writes below ``folder``: the folders it had to create are removed
    again when the block fails or is interrupted before anything was written in them, so a run stopped early
    leaves no empty output folder behind (``rmdir`` removes only an empty folder; a folder in use stays)."""
    folder = Path(folder)
    created = [p for p in (folder, *folder.parents) if not p.exists()]  # deepest first
    try:
        writable_folder(folder, option)
        yield
    except BaseException:
        for path in created:
            try:
                path.rmdir()
            except OSError:
                break
        raise


def _is_result(folder: Path) -> bool:
    """A folder ``run`` or ``sweep`` wrote: it has their ``manifest.json`` and ``metrics.csv``."""
    return (folder / "manifest.json").is_file() and (folder / "metrics.csv").is_file()


def replaceable(target: Path) -> None:
    """Refuse (a :class:`~marinebench.errors.ConfigError` naming ``target``) to replace what is not marinebench's: a
    results folder is written whole in place of the previous one, so ``target`` must be absent, an empty folder, or
    a folder with the ``manifest.json`` and ``metrics.csv`` of a ``run`` or ``sweep`` (a web app's folder has a
    manifest.json too). A file, a symbolic link or a folder of other things at that path (a config named after a
    source folder, ``--out .``) is someone's work; before, it was replaced and lost. Nor may ``target`` lie inside
    a results folder (``--out results/torben_fig1``): it would be lost when that folder is next replaced."""
    from marinebench.errors import ConfigError

    target = Path(target)
    if inside := next((p for p in target.absolute().parents if _is_result(p)), None):
        raise ConfigError(str(target), "", f"inside the results folder {inside}, which is replaced whole when it is "
                          "written again: not written there (choose another --out)")
    if target.is_symlink():
        raise ConfigError(str(target), "", "a symbolic link, not a results folder: not replaced (remove it, or choose "
                          "another --out)")
    if not target.exists():
        return
    if not target.is_dir():
        raise ConfigError(str(target), "", "a file, not a results folder: not replaced (move it, or choose another --out)")
    if not _is_result(target) and any(target.iterdir()):
        raise ConfigError(str(target), "", "a folder of other files (no manifest.json and metrics.csv), not marinebench's "
                          "results: not replaced (move it, or choose another --out)")


def replaceable_file(path: Path, heads: tuple[str, ...], option: str) -> None:
    """Refuse (a :class:`~marinebench.errors.ConfigError` naming ``option`` and ``path``) to replace a file this
    command did not write: ``path`` must be absent, empty, or a file whose text starts with one of ``heads`` (how
    the command's outputs start). Before, ``report --out results/x/metrics.csv`` replaced the result's metrics with
    HTML (rc 0), and ``compare --output`` any file with the comparison."""
    from marinebench.errors import ConfigError

    path = Path(path)
    if path.is_symlink() or (path.exists() and not path.is_file()):
        what = "a symbolic link" if path.is_symlink() else "not a file"
        raise ConfigError(option, "", f"{path}: {what}: not replaced (choose another {option})")
    if not path.exists() or path.stat().st_size == 0:
        return
    try:
        with open(path, "rb") as fh:
            start = fh.read(max(len(h.encode()) for h in heads))
    except OSError as exc:
        raise ConfigError(option, "", f"{path}: cannot read what is there ({exc.strerror}): not replaced") from None
    if not any(start.startswith(h.encode()) for h in heads):
        raise ConfigError(option, "", f"{path}: a file this command did not write: not replaced (move it, or choose "
                          f"another {option})")


@contextmanager
def atomic_directory(target: Path, results: bool = True) -> Iterator[Path]:
    """Yield a temporary directory that replaces ``target`` only if the block succeeds (``results``: ``target`` is
    a results folder, checked by :func:`replaceable` first; ``figures/`` inside one is not)."""
    target = Path(target)
    if results:
        replaceable(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    _remove_orphans(target)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.tmp-{_owner()}-", dir=target.parent))
    os.chmod(tmp, 0o777 & ~_umask())  # mkdtemp makes 0700; results are for everyone the umask allows
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if target.exists() and _exchange(tmp, target):  # tmp now holds the previous results
        if tmp.is_dir():
            shutil.rmtree(tmp, ignore_errors=True)
        else:
            tmp.unlink()
        return
    old = None
    if target.exists():  # no atomic exchange here: the previous results step aside for a moment
        old = Path(tempfile.mkdtemp(prefix=f".{target.name}.old-{_owner()}-", dir=target.parent))
        os.replace(target, old / "x")
    os.replace(tmp, target)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def _host() -> str:
    return socket.gethostname().replace("-", "_")  # '-' separates the name's fields


def _owner() -> str:
    return f"{_host()}-{os.getpid()}"


def _remove_orphans(target: Path) -> None:
    """Remove the temporary siblings of ``target`` (``.<name>.tmp-<host>-<pid>-*``, ``.<name>.old-...``) whose
    writer, a process of this host, no longer exists. Those of other hosts (a shared file system) and of live
    processes (a concurrent write) are left alone."""
    host = _host()
    for kind in ("tmp", "old"):
        for path in target.parent.glob(f".{glob.escape(target.name)}.{kind}-{host}-*-*"):
            pid = path.name.removeprefix(f".{target.name}.{kind}-{host}-").split("-", 1)[0]
            if pid.isdigit() and not _alive(int(pid)):
                shutil.rmtree(path, ignore_errors=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: alive
        pass
    return True


def _exchange(a: Path, b: Path) -> bool:
    """Swap two existing paths in one step, Linux's ``renameat2(RENAME_EXCHANGE)``, so that ``b`` never stops
    existing: a kill at any moment leaves the old results or the new ones in place. False where the platform, its
    C library (glibc >= 2.28) or the file system has no such call; the caller then renames twice."""
    if not sys.platform.startswith("linux"):
        return False
    import ctypes

    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    at_fdcwd, rename_exchange = -100, 2  # <fcntl.h>, <linux/fs.h>
    return renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0


def atomic_write_text(path: Path, text: str) -> None:
    """Write a single file atomically (temp file + rename); a failed or interrupted write leaves the previous file
    and no temporary one."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp makes 0600: give the file an ordinary file's mode
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text(encoding="utf-8", errors="replace").splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def machine() -> dict[str, object]:
    """The hardware a result was computed on. numpy picks its vector kernels (and OpenBLAS its kernels) by CPU at
    import, so the same code, seeds and versions can differ in the last digits between machines (the resetting
    observer's threshold tests can carry such a difference into the fifth digit of a KPI); on one machine
    reruns are byte-identical. Recorded so that such a difference is explained, not searched for."""
    import numpy as np
    from threadpoolctl import threadpool_info

    simd = np.show_config(mode="dicts").get("SIMD Extensions", {})
    blas = sorted({f"{i['internal_api']} {i.get('architecture', '')}".strip() for i in threadpool_info()})
    return {"platform": platform.platform(), "cpu": _cpu_model(), "cores": os.cpu_count(),
            "numpy_simd": simd.get("found", []), "blas": blas}


def git_revision() -> str:
    """``<sha>`` or ``<sha>-dirty`` of the source tree, or ``unknown`` when the imported package is not the one of a
    git checkout: an installed copy (``pip install .``) lies in site-packages, which may sit inside a checkout (a
    ``.venv`` in it) whose HEAD need not be the code that runs; :func:`~marinebench.provenance.package_digest`,
    which every manifest also records as ``source_digest``, names the code either way."""
    root = Path(__file__).resolve().parents[2]  # the checkout holding marinebench/ (an editable install)
    try:
        sha = subprocess.run(["git", "rev-parse", "--show-toplevel", "HEAD"], cwd=root, capture_output=True,
                             encoding="utf-8", errors="replace", timeout=10, check=False)
        lines = sha.stdout.splitlines()
        if sha.returncode or len(lines) != 2 or Path(lines[0]).resolve() != root:
            return "unknown"
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--", "marinebench", "configs", "scenarios", "pyproject.toml"],
            cwd=root, capture_output=True, encoding="utf-8", errors="replace", timeout=10, check=False,
        )
        return lines[1].strip() + ("-dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def _program() -> str:
    """The command's name as a shell would take it back: ``marinebench`` for the console script and for ``python -m
    marinebench`` (or ``-m marinebench.cli``), whose ``argv[0]`` is the module's file; else the script's name (a
    Python program calling the API)."""
    here = Path(__file__).resolve().parents[1]
    try:
        started = Path(sys.argv[0]).resolve()
    except (OSError, RuntimeError):  # a loop of symbolic links
        return Path(sys.argv[0]).name
    return "marinebench" if started in (here / "__main__.py", here / "cli" / "__main__.py") else Path(sys.argv[0]).name


def manifest(**fields) -> str:
    doc = {
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        "command": shlex.join([_program(), *sys.argv[1:]]),  # quoted: pastes back into a shell
        "git_revision": git_revision(),
        "source_digest": package_digest(),
        "versions": versions(),
        "machine": machine(),
        **fields,
    }
    return json.dumps(doc, indent=2, default=float)
