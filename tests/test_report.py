"""The HTML report: self-contained, every table and figure present, rendered by a real headless browser."""

import json
import re
import shutil
import subprocess
from html import escape

import pytest
from matplotlib import image
from typer.testing import CliRunner

from marinebench.cli import app
from marinebench.results.report import claims_overview, markdown_to_html, render_report

from .conftest import write_tiny

runner = CliRunner()
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]


@pytest.fixture(scope="module")
def report(tmp_path_factory, request):
    tiny = request.getfixturevalue("tiny_config_module")
    root = tmp_path_factory.mktemp("rep")
    for name in ("base", "new"):
        assert runner.invoke(app, ["run", str(tiny), "--out", str(root / name), "--quiet"]).exit_code == 0
    out = root / "report.html"
    res = runner.invoke(app, ["report", str(root / "new"), "--out", str(out), "--compare", str(root / "base")])
    assert res.exit_code == 0, res.output
    return root, out


@pytest.fixture(scope="module")
def tiny_config_module(tmp_path_factory):
    return write_tiny(tmp_path_factory.mktemp("cfg"), horizon=3.0)


def test_report_is_self_contained_with_every_table_and_figure(report):
    root, out = report
    html = out.read_text()
    assert "<script" not in html and not re.search(r'(src|href)="https?:', html)
    assert html.count("<img ") == len(list((root / "new").rglob("*.png"))) == 2
    assert html.count("data:image/png;base64,") == 2
    assert "tiny" in html and "e_sigma_u paper" in html and "Comparison with" in html
    for variant in ("liu_eps0.2", "proposed_d1.2"):
        assert variant in html
    assert "0 worse, 0 better, 12 same" in html


def chromium() -> str:
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        pytest.fail("Debian's chromium is required for the browser test (.ci/run installs it with apt)")
    return exe


def test_report_renders_in_headless_chromium(report, tmp_path):
    _root, out = report
    # visible text: a copy of the page with a one-line script that writes document.body.innerText into the DOM
    probe = tmp_path / "probe.html"
    probe.write_text(out.read_text().replace(
        "</body>", "<script>var p=document.createElement('pre');p.id='visible';"
                   "p.textContent=document.body.innerText;document.body.appendChild(p);</script></body>"))
    dom = subprocess.run([chromium(), *FLAGS, f"--user-data-dir={tmp_path / 'u1'}", "--dump-dom", probe.as_uri()],
                         capture_output=True, text=True, timeout=120, check=True).stdout
    visible = dom[dom.index('id="visible"'):]
    for text in ("tiny", "liu_eps0.2", "proposed_d1.2", "e_u ours", "e_u paper", "0 worse, 0 better, 12 same"):
        assert text in visible, text
    shot = tmp_path / "shot.png"
    subprocess.run([chromium(), *FLAGS, f"--user-data-dir={tmp_path / 'u2'}", "--window-size=1200,1600",
                    f"--screenshot={shot}", out.as_uri()], capture_output=True, timeout=120, check=True)
    img = image.imread(shot)[..., :3]
    nonwhite = (img.mean(axis=2) < 0.9).mean()
    assert img.std() > 0.05 and nonwhite > 0.02  # not blank


def test_report_compares_other_root_seeds_only_unpaired(report, tmp_path):
    """A run on another root seed: the paired comparison refuses it in one line naming --unpaired, which the
    report takes too; --unpaired without --compare has nothing to act on."""
    root, _ = report
    tiny = next(root.glob("new/*/config.resolved.yaml")).parent
    assert runner.invoke(app, ["run", str(tiny / "config.resolved.yaml"), "--seed", "7", "--out", str(tmp_path / "s7"),
                               "--quiet"]).exit_code == 0
    args = ["report", str(tmp_path / "s7"), "--out", str(tmp_path / "r.html"), "--compare", str(root / "base")]
    paired = runner.invoke(app, args)
    assert paired.exit_code == 2 and "--unpaired compares them" in paired.output and not (tmp_path / "r.html").exists()
    res = runner.invoke(app, [*args, "--unpaired"])
    assert res.exit_code == 0, res.output
    html = (tmp_path / "r.html").read_text()
    assert "Comparison with" in html and "Unpaired: each side" in html and "12 same" in html
    alone = runner.invoke(app, ["report", str(tmp_path / "s7"), "--out", str(tmp_path / "x.html"), "--unpaired"])
    assert alone.exit_code == 2 and "needs --compare BASELINE" in alone.output


def test_markdown_subset_becomes_the_right_html():
    """Headings keep their level, lists and pipe tables their structure (separator row dropped), inline code,
    bold and italic are marked up, and everything else is escaped."""
    md = ("# Title\n### Sub `a<b`\n\npara **bold** and *it* & more\n- one\n- two *x*\n\n"
          "| a | b |\n|---|:-:|\n| 1 | `c` |\ntext")
    assert markdown_to_html(md).splitlines() == [
        "<h2>Title</h2>", "<h4>Sub <code>a&lt;b</code></h4>",
        "<p>para <b>bold</b> and <i>it</i> &amp; more</p>",
        "<ul>", "<li>one</li>", "<li>two <i>x</i></li>", "</ul>",
        '<div class="scroll"><table><thead><tr><th>a</th><th>b</th></tr></thead><tbody>',
        "<tr><td>1</td><td><code>c</code></td></tr>", "</tbody></table></div>", "<p>text</p>"]
    assert markdown_to_html("###### six") == "<h6>six</h6>"  # h7 does not exist
    # a pipe escaped in a cell (results/tables.py md_cell: a label "RISE | old", a claim about |e_u|) stays in its cell
    table = markdown_to_html("| claim | n |\n|---|---|\n| \\|e_u\\| \\| x | 2 |")
    assert "<tr><td>|e_u| | x</td><td>2</td></tr>" in table


def test_report_shows_each_manifest_and_the_claims_overview(report, tmp_path):
    root, out = report
    html = out.read_text()
    manifest = json.loads(next((root / "new").rglob("manifest.json")).read_text())
    assert f"<tr><th>seed</th><td>{manifest['seed']}</td></tr>" in html
    assert f"<tr><th>runs</th><td>{manifest['runs']}</td></tr>" in html
    assert f"<tr><th>source_digest</th><td>{manifest['source_digest']}</td></tr>" in html  # the code, installed or not
    assert "(no manifest)" not in html and "<p>Assumptions:</p>" in html
    name = next((root / "new").rglob("manifest.json")).parent.name
    assert f'<li><a href="#{name}">{name}</a></li>' in html and html.count(f'<h2 id="{name}">{name}</h2>') == 1
    assert all(f"<li>{escape(a)}</li>" in html for a in manifest["assumptions"])
    direct = render_report(root / "new", compare_with=root / "base")  # the API pairs seeds by default, as the CLI
    assert "Comparison with" in direct and "Unpaired" not in direct
    bare = tmp_path / "bare"
    shutil.copytree(root / "new", bare)
    next(bare.rglob("manifest.json")).unlink()  # a results folder made by hand or by another tool
    text = render_report(bare)
    assert "<p>(no manifest)</p>" in text and "<p>Assumptions:</p>" not in text
    assert "claims</h3>" not in html  # the tiny experiment states no claims: no overview
    claimed = tmp_path / "claimed"
    shutil.copytree(root / "new", claimed)
    path = next(claimed.rglob("manifest.json"))
    path.write_text(json.dumps(manifest | {"claims": [{"text": "a below b", "source": "T", "holds": True}]}))
    text = render_report(claimed)
    assert "claims</h3>" in text and f"<td>{name}</td><td>1\u00a0of\u00a01</td>" in text


def test_claims_overview_counts_what_holds_and_lists_what_fails(tmp_path):
    claims = [{"text": "a > b", "source": "T", "holds": True}, {"text": "c | d", "source": "T", "holds": False},
              {"text": "unchecked", "source": "T", "holds": False, "not_checked": "no such signal"}]
    narrow = [{"text": "e < f", "source": "T", "holds": True, "narrowly": True},
              {"text": "g < h", "source": "T", "holds": False, "narrowly": True}]
    for name, entries in (("x", claims), ("y", []), ("z", claims[:1]), ("w", narrow)):
        (tmp_path / name).mkdir()
        (tmp_path / name / "manifest.json").write_text(json.dumps({"claims": entries}))
    md = claims_overview({n: tmp_path / n for n in ("x", "y", "z", "w")})
    rows = [line for line in md.splitlines() if line.startswith(("| x", "| y", "| z", "| w"))]
    # c | d escaped, so that the report shows it in one cell
    assert rows == ["| x | 1\u00a0of\u00a03 | c \\| d |", "| z | 1\u00a0of\u00a01 |  |",
                    "| w | 1\u00a0of\u00a02 (1 narrowly) | g < h (narrowly) |"]
    assert claims_overview({"y": tmp_path / "y"}) == ""
