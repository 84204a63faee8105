"""What a result is computed from, as digests: whether a stored result (or a sweep's finished batches) is
still current, and whether Dask workers run the same code.

:func:`inputs_key` covers the resolved experiment (seeds, every default filled in), the marinebench source,
the versions of the numerical packages and the files of ``kind: custom`` classes. ``marinebench run
--resume`` skips an experiment whose ``manifest.json`` has the same key; an interrupted sweep reuses its
finished batches only under the same key.
"""

from __future__ import annotations

import hashlib
import json
from functools import cache
from pathlib import Path


@cache
def package_digest() -> str:
    """SHA-256 over the marinebench package's Python files (relative names and bytes), hashed once per process:
    the source as this process found it, which is also the code it imported (a run or sweep asks several times)."""
    root = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        h.update(path.relative_to(root).as_posix().encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def custom_sources(exp) -> list[str]:
    """The ``source`` of every custom observer and controller class the experiment's variants use."""
    parts = [p for v in exp.variants for p in (v.observer, v.controller) if p is not None]
    return sorted({p.source for p in parts if p.kind == "custom"})


def inputs_key(exp) -> str:
    """SHA-256 of everything an experiment's numbers depend on (see the module docstring)."""
    from marinebench.plugins import source_digest
    from marinebench.results.writer import versions

    h = hashlib.sha256()
    for part in (exp.model_dump_json(), package_digest(), json.dumps(versions(), sort_keys=True)):
        h.update(part.encode())
    for source in custom_sources(exp):
        h.update(f"{source}\0{source_digest(source)}".encode())
    return h.hexdigest()
