"""The HTML report: self-contained, every table and figure present, rendered by a real headless browser."""

import re
import shutil
import subprocess

import pytest
from matplotlib import image
from typer.testing import CliRunner

from marinebench.cli import app

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
