"""One self-contained static HTML report of a results tree: tables, figures (embedded), manifests."""

from __future__ import annotations

import base64
import html
import re
from pathlib import Path

from marinebench.results.compare import compare_dirs, find_results, to_markdown
from marinebench.results.stored import read_manifest, read_text
from marinebench.results.tables import md_row, md_split

CSS = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1200px; color: #222; }
h1 { border-bottom: 2px solid #246; } h2 { margin-top: 2em; color: #246; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.85em; }
.scroll { overflow-x: auto; } /* a wide table scrolls by itself, not the page */
th, td { border: 1px solid #bbb; padding: 3px 7px; text-align: left; }
th { background: #eef2f7; } tr:nth-child(even) td { background: #fafafa; }
img { max-width: 100%; border: 1px solid #ddd; margin: 0.5em 0; }
.manifest { font-size: 0.85em; background: #f6f6f6; padding: 0.6em 1em; }
code { background: #f0f0f0; padding: 0 3px; }
"""


#: How a report starts: ``report --out`` replaces a file only when it starts so (a report written before).
HEAD = "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>marinebench report</title>"


def _inline(text: str) -> str:
    out = html.escape(text)
    out = re.sub(r"`([^`]+)`", r"<code>\1</code>", out)
    out = re.sub(r"\*\*([^*]+)\*\*", r"<b>\1</b>", out)
    return re.sub(r"\*([^*\s][^*]*)\*", r"<i>\1</i>", out)


def markdown_to_html(md: str) -> str:
    """The markdown subset marinebench writes: headings, paragraphs, bullet lists and pipe tables."""
    out: list[str] = []
    lines = md.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("|"):
            rows = []
            while i < len(lines) and lines[i].startswith("|"):
                cells = md_split(lines[i])
                if not all(set(c) <= set("-: ") for c in cells):
                    rows.append(cells)
                i += 1
            head, body = rows[0], rows[1:]
            out.append('<div class="scroll"><table><thead><tr>' + "".join(f"<th>{_inline(c)}</th>" for c in head)
                       + "</tr></thead><tbody>")
            out += ["<tr>" + "".join(f"<td>{_inline(c)}</td>" for c in r) + "</tr>" for r in body]
            out.append("</tbody></table></div>")
            continue
        if line.startswith("#"):
            level = min(len(line) - len(line.lstrip("#")) + 1, 6)
            out.append(f"<h{level}>{_inline(line.lstrip('#').strip())}</h{level}>")
        elif line.startswith("- "):
            out.append("<ul>")
            while i < len(lines) and lines[i].startswith("- "):
                out.append(f"<li>{_inline(lines[i][2:])}</li>")
                i += 1
            out.append("</ul>")
            continue
        elif line.strip():
            out.append(f"<p>{_inline(line)}</p>")
        i += 1
    return "\n".join(out)


def _manifest_html(d: Path) -> str:
    m = read_manifest(d)
    if not m:
        return "<p>(no manifest)</p>"
    keys = ["created", "git_revision", "source_digest", "model", "seed", "seeds", "runs", "diverged_runs", "dt", "horizon", "wall_time_s", "command"]
    rows = "".join(f"<tr><th>{k}</th><td>{html.escape(str(m.get(k, '')))}</td></tr>" for k in keys if k in m)
    versions = ", ".join(f"{k} {v}" for k, v in m.get("versions", {}).items())
    assumptions = "".join(f"<li>{html.escape(a)}</li>" for a in m.get("assumptions", []))
    return (f'<div class="manifest"><table>{rows}<tr><th>versions</th><td>{html.escape(versions)}</td></tr></table>'
            f"<p>Assumptions:</p><ul>{assumptions}</ul></div>")


def claims_overview(dirs: dict[str, Path]) -> str:
    """A markdown table of the claims of every result directory (from the manifests): how many hold, and which
    fail; a verdict whose interval reaches across its bound is marked *narrowly*."""
    rows = []
    for name, d in dirs.items():
        claims = read_manifest(d).get("claims", [])
        if claims:
            held = [c for c in claims if c["holds"]]
            narrow = sum(bool(c.get("narrowly")) for c in held)
            failing = [c["text"] + (" (narrowly)" if c.get("narrowly") else "")
                       for c in claims if not c["holds"] and not c.get("not_checked")]
            rows.append(md_row([name, f"{len(held)}\u00a0of\u00a0{len(claims)}" + (f" ({narrow} narrowly)" if narrow else ""),
                                "; ".join(failing)]))
    if not rows:
        return ""
    return "\n".join(["## The papers' claims", "", "Checked on our runs (each experiment's claims.md below).", "",
                      "| experiment | hold | failing |", "|---|---|---|", *rows]) + "\n"


def render_report(results: Path, compare_with: Path | None = None, paired: bool = True) -> str:
    dirs = find_results(results)
    parts = [f"<h1>marinebench report: {html.escape(str(results))}</h1>",
             ("<p>Tables show our results (mean and 95% CI over seeds) beside the papers' published values, which "
             "are in columns labelled <i>paper</i> and are copied, not computed.</p>")]
    parts.append("<ul>" + "".join(f'<li><a href="#{n}">{html.escape(n)}</a></li>' for n in dirs) + "</ul>")
    if overview := claims_overview(dirs):
        parts.append(markdown_to_html(overview))
    if compare_with is not None:
        table = compare_dirs(compare_with, results, paired=paired)
        parts.append(f"<h2 id='comparison'>Comparison with {html.escape(str(compare_with))}</h2>")
        parts.append(markdown_to_html(to_markdown(table, "compare", paired=paired)))
    for name, d in dirs.items():
        parts.append(f'<h2 id="{html.escape(name)}">{html.escape(name)}</h2>')
        for md in ("table.md", "claims.md"):
            if (d / md).exists():
                parts.append(markdown_to_html(read_text(d / md)))
        for png in sorted((d / "figures").glob("*.png")):
            data = base64.b64encode(png.read_bytes()).decode()
            parts.append(f'<figure><img alt="{html.escape(png.name)}" src="data:image/png;base64,{data}">'
                         f"<figcaption>{html.escape(png.name)}</figcaption></figure>")
        parts.append(_manifest_html(d))
    return HEAD + f"<style>{CSS}</style></head><body>" + "\n".join(parts) + "</body></html>\n"
