"""What a result is computed from, as digests: whether a stored result (or a sweep's finished batches) is
still current, and whether Dask workers run the same code.

:func:`inputs_key` covers the resolved experiment (seeds, every default filled in), the marinebench code,
the versions of the numerical packages and the files of ``kind: custom`` classes (each class's file and the files
of your own code it imports: ``plugins.source_files``). ``marinebench run --resume`` skips an experiment whose
``manifest.json`` has the same key; an interrupted sweep reuses its finished batches only under the same key.
"""

from __future__ import annotations

import hashlib
import io
import json
import re
import tokenize
from functools import cache
from pathlib import Path


@cache
def package_digest() -> str:
    """SHA-256 over the marinebench package's Python files (relative names and :func:`code_text`), hashed once per
    process: the code as this process found it, which is also the code it imported (a run or sweep asks several
    times). Comments and docstrings are left out, so that a change to them alone leaves stored results current;
    the manifest's ``git_revision`` names the exact files."""
    root = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        h.update(path.relative_to(root).as_posix().encode() + b"\0")
        h.update(code_text(path.read_text(encoding="utf-8")).encode())
    return h.hexdigest()


_LINE_START = {tokenize.NEWLINE, tokenize.NL, tokenize.INDENT, tokenize.DEDENT}  # the token before a line's first


def code_text(source: str) -> str:
    """A Python file's text without what cannot change what it computes: comments, statements that are a string
    alone (docstrings) on lines of their own, blank lines and trailing spaces; one pass of the tokenizer, the same
    text on every Python version (f-strings, which 3.12 tokenizes apart, always count). Rewrapping a line of code
    still changes it."""
    lines = source.splitlines()
    dropped: set[int] = set()
    before, alone = tokenize.NEWLINE, None  # alone: a string that began a line, while it may be a statement
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.COMMENT:
            row, col = token.start
            lines[row - 1] = lines[row - 1][:col]
            continue
        if alone is not None and token.type == tokenize.NEWLINE:  # nothing but the string in its statement
            dropped.update(range(alone.start[0], alone.end[0] + 1))
        alone = token if (token.type == tokenize.STRING and before in _LINE_START
                          and "f" not in re.match(r"[A-Za-z]*", token.string)[0].lower()) else None
        before = token.type
    return "\n".join(line.rstrip() for i, line in enumerate(lines, 1) if i not in dropped and line.strip())


def custom_sources(exp) -> list[str]:
    """The ``source`` of every custom observer and controller class the experiment's variants use."""
    parts = [p for v in exp.variants for p in (v.observer, v.controller) if p is not None]
    return sorted({p.source for p in parts if p.kind == "custom"})


def inputs_key(exp) -> str:
    """SHA-256 of everything an experiment's numbers depend on (see the module docstring)."""
    from marinebench.plugins import file_digest, source_files
    from marinebench.results.writer import versions

    h = hashlib.sha256()
    for part in (exp.model_dump_json(), package_digest(), json.dumps(versions(), sort_keys=True)):
        h.update(part.encode())
    for source in custom_sources(exp):
        h.update(source.encode())
        for path in source_files(source):
            h.update(f"\0{path}\0{file_digest(path)}".encode())
    return h.hexdigest()
