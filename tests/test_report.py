"""The sign-off report: one self-contained page (tables, inline SVG figures, the 3D scene, provenance)."""

from __future__ import annotations

import hashlib
import html
import json
import re
import subprocess
import tempfile
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("meshcat")
pytest.importorskip("matplotlib")

from pkmtol.cli import main  # noqa: E402
from pkmtol.design.job import DesignOptions, allocate  # noqa: E402
from pkmtol.exceptions import FiguresError, OutputError  # noqa: E402
from pkmtol.model.loader import load_mechanism  # noqa: E402
from pkmtol.present import html_report  # noqa: E402
from pkmtol.present.html_report import CSP, markdown_sections, render_report, svg_inline, write_report  # noqa: E402
from pkmtol.present.provenance import provenance, sha256  # noqa: E402
from pkmtol.present.viewer.browser import chromium_command, find_chromium  # noqa: E402

ROBOT = Path(__file__).resolve().parents[1] / "robots" / "r2rps_ups"
#: Attributes through which a page can make the browser fetch something.
FETCHING = {
    "src",
    "href",
    "srcset",
    "poster",
    "data",
    "action",
    "formaction",
    "background",
    "xlink:href",
    "ping",
}
LOCAL = ("data:", "blob:", "about:", "#", "javascript:void")


class _Resources(HTMLParser):
    """Every URL the markup would fetch (attributes, CSS ``url()``, ``@import``), srcdoc frames included."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.urls: list[str] = []
        self.srcdocs: list[str] = []
        self._style = False

    def handle_starttag(self, tag, attrs):
        self._style = tag == "style"
        for name, value in attrs:
            if value is None:
                continue
            if name == "srcset":
                self.urls.extend(u.strip().split(" ")[0] for u in value.split(","))
            elif name in FETCHING:
                self.urls.append(value.strip())
            if name == "style":
                self.urls.extend(_css_urls(value))
            if name == "srcdoc":
                self.srcdocs.append(value)
            if tag == "meta" and name == "content" and ("refresh" in dict(attrs).get("http-equiv", "")):
                self.urls.append(value)

    def handle_data(self, data):
        if self._style:
            self.urls.extend(_css_urls(data))

    def handle_endtag(self, tag):
        self._style = False


def _css_urls(css: str) -> list[str]:
    found = re.findall(r"url\(\s*['\"]?([^'\")]+)", css) + re.findall(r"@import\s+['\"]([^'\"]+)", css)
    return [u.strip() for u in found]


def external_urls(page: str) -> list[str]:
    """URLs the page (and the documents of its srcdoc frames) would fetch from outside itself."""
    parser = _Resources()
    parser.feed(page)
    out = [u for u in parser.urls if u and not u.lower().startswith(LOCAL)]
    for doc in parser.srcdocs:
        out += external_urls(doc)
    return out


def test_the_external_url_check_finds_what_it_must():
    """The check itself: a page that would fetch anything, in any of these ways, is caught."""
    bad = (
        '<img src="https://cdn.example/x.png"><link rel="stylesheet" href="//fonts.example/f.css">'
        '<div style="background:url(http://img.example/b.png)"></div><style>@import "https://s.example/a.css";'
        '</style><svg><image xlink:href="http://i.example/i.png"/></svg>'
        '<iframe srcdoc="&lt;script src=&quot;https://js.example/m.js&quot;&gt;&lt;/script&gt;"></iframe>'
    )
    assert len(external_urls(bad)) == 6
    assert external_urls('<img src="data:image/png;base64,AA"><a href="#scene">x</a>') == []


@pytest.fixture(scope="module")
def result():
    return allocate(
        load_mechanism(ROBOT),
        # the FOSM design: its capability (27086 PPM) and sections are pinned below
        DesignOptions(samples=1000, exact_samples=5, verification_poses=100, claim_poses=30, method="fosm"),
    )


@pytest.fixture(scope="module")
def report(result, tmp_path_factory):
    path = tmp_path_factory.mktemp("report") / "report.html"
    prov = provenance(
        result.mechanism, 0, ["/usr/bin/pkmtol", "allocate", "robots/r2rps_ups", "--report", "r.html"]
    )
    rep = write_report(result, path, prov)
    return path, rep, path.read_text(encoding="utf-8")


def test_page_holds_every_part_and_fetches_nothing(report):
    path, rep, page = report
    assert external_urls(page) == []
    assert f'<meta http-equiv="Content-Security-Policy" content="{CSP}">' in page
    assert "default-src 'none'" in CSP and "http" not in CSP
    # the 3D scene is embedded whole (meshcat's viewer and the scene's commands)
    frame = re.search(r'<iframe class="pkmtol-scene-frame"[^>]*srcdoc="([^"]*)"', page)
    assert frame is not None
    scene = html.unescape(frame.group(1))
    assert "MeshCat.Viewer" in scene and 'id="pkmtol-legend"' in scene
    assert scene.count('fetch("data:application/octet-binary;base64,') >= 147
    assert rep.scene is not None and rep.scene.spheres.count == 147
    # four figures, inline SVG, each in its own id space
    assert rep.figures == ("sensitivity", "dlambda_histogram", "tolerances", "contributions")
    outside = page.replace(frame.group(0), "")
    assert outside.count("<svg") == 4 and outside.count('class="pkmtol-figure"') == 4
    ids = re.findall(r'\bid="([^"]+)"', outside)
    assert len(ids) == len(set(ids)) > 100
    for ref in re.findall(r'href="#([^"]+)"', outside) + re.findall(r"url\(#([^)]+)\)", outside):
        assert ref in ids  # every clip path and glyph reference resolves
    # every section of the text report, tables as HTML tables
    for heading in (
        "Tolerances of the uncompensatable errors (FOSM, paper Table III)",
        "Contributions to E[Δλ²] (percent contribution, Pareto)",
        "Stack-up of the drawing tolerances (±t = 3σ)",
        "Drawing tolerances (±t = 3σ)",
        "Claimed vs true reliability of the FOSM designs (R in %)",
    ):
        assert heading in rep.sections and f"<h2>{html.escape(heading)}</h2>" in page
    assert outside.count("<table") == 10  # the eight of the text report, at a glance, provenance
    assert "27086 PPM out of spec" in page and "δφ_{1,4}" in page
    # the Pareto figure sits in the contributions section
    contrib = page.index("Contributions to E[Δλ²] (percent contribution")
    assert contrib < page.index('id="figure-contributions"') < page.index("Stack-up of the drawing")
    assert path.stat().st_size == len(rep.data)


def test_provenance(report, result):
    _, _, page = report
    files = [ROBOT / "mechanism.toml", *(limb.urdf_path for limb in result.mechanism.limbs)]
    for f in files:
        digest = hashlib.sha256(f.read_bytes()).hexdigest()
        assert digest == sha256(f)
        assert f"SHA-256 {f.name}" in page and digest in page
    assert "pkmtol allocate robots/r2rps_ups --report r.html" in page  # argv[0] shown as pkmtol
    assert "<td>seed</td><td><code>0</code></td>" in page
    prov = provenance(result.mechanism)
    assert prov.version == "0.1.0" and prov.seed is None and prov.command_line is None
    if prov.commit is not None:  # run from the git checkout
        assert re.fullmatch(r"[0-9a-f]{40}(\+dirty)?", prov.commit)
        assert prov.commit.split("+")[0] in page
    assert any(r[0] == "software" and "Pinocchio" in r[1] for r in prov.rows())


def test_markdown_sections_and_svg_ids():
    md = "# T\n\nintro\n\n## A\n\n| x | y |\n|---|---|\n| 1.5 | a<b |\n\ntext\n"
    sections = markdown_sections(md)
    assert [h for h, _ in sections] == ["T", "A"]
    assert '<td class="num">1.5</td><td>a&lt;b</td>' in sections[1][1] and "<p>text</p>" in sections[1][1]
    svg = (
        '<?xml version="1.0"?>\n<!DOCTYPE svg><svg xmlns="http://www.w3.org/2000/svg"><metadata>x</metadata>'
    )
    svg += '<defs><path id="g1"/></defs><use xlink:href="#g1"/><g clip-path="url(#c1)"/></svg>'
    out = svg_inline(svg, "fig")
    assert out.startswith("<svg>") and 'id="fig-g1"' in out and 'href="#fig-g1"' in out
    assert "url(#fig-c1)" in out and "metadata" not in out and "http" not in out


def test_without_matplotlib_the_report_says_so(result, monkeypatch):
    def missing(_):
        raise FiguresError("the figures need matplotlib (test)")

    monkeypatch.setattr(html_report, "figure_svgs", missing)
    rep = render_report(result, scene=False)
    page = rep.data.decode("utf-8")
    assert rep.figures == () and "matplotlib (test)" in rep.figures_missing and "matplotlib (test)" in page
    assert "<svg" not in page and rep.scene is None


def test_written_whole_or_not_at_all(result, tmp_path):
    with pytest.raises(OutputError, match="does not exist"):
        write_report(result, tmp_path / "missing" / "r.html")
    assert list(tmp_path.iterdir()) == []


def test_allocate_report_option(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "1000")  # whole lines to match (piped output wraps at 100)
    out, rep = tmp_path / "out", tmp_path / "report.html"
    small = ["--samples", "400", "--exact-samples", "5", "--verification-poses", "40", "--no-progress"]
    small += ["--method", "fosm"]  # the report of the FOSM design (9 sections)
    args = [
        "allocate",
        str(ROBOT),
        "--out",
        str(out),
        "--report",
        str(rep),
        "--drawing-k",
        "2",
        "--no-figures",
    ]
    assert main([*args, *small, "--seed", "3"]) == 0
    text = capsys.readouterr().out
    assert f"wrote {rep} ({rep.stat().st_size} bytes: 9 sections, 4 figures)" in text
    page = rep.read_text(encoding="utf-8")
    assert "<td>seed</td><td><code>3</code></td>" in page and "±t = 2σ" in page
    command = html.escape(f"pkmtol allocate {ROBOT} --out {out} --report {rep} --drawing-k 2 --no-figures")
    assert command in page  # the command as typed, not the test runner's
    doc = json.loads((out / "allocation.json").read_text(encoding="utf-8"))
    assert doc["signoff"]["convention"] == {
        "kind": "normal",
        "factor": 2.0,
        "text": "±t = 2·σ (normal: a Gaussian process keeps 95.45 % of its parts inside ±t)",
    }
    # bad requests stop before any computation and write nothing
    never = tmp_path / "never"
    assert (
        main(["allocate", str(ROBOT), "--out", str(never), "--drawing", "uniform", "--drawing-k", "3"]) == 2
    )
    assert "uniform convention has none" in capsys.readouterr().err
    assert main(["allocate", str(ROBOT), "--out", str(never), "--drawing-k", "-1"]) == 2
    assert "--drawing-k" in capsys.readouterr().err
    assert (
        main(["allocate", str(ROBOT), "--out", str(never), "--report", str(tmp_path / "no" / "r.html")]) == 2
    )
    assert "does not exist" in capsys.readouterr().err
    assert not never.exists() or not any(never.iterdir())


# --- the page in a browser ---------------------------------------------------------------------

_PROBE = (
    "<script>window.addEventListener('load',()=>{const r={height:document.documentElement.scrollHeight};"
    "for(const [k,s] of [['scene','iframe.pkmtol-scene-frame'],['figure','figure.pkmtol-figure svg'],"
    "['table','section.pkmtol-tables table']]){r[k]=[...document.querySelectorAll(s)].map(e=>{"
    "const b=e.getBoundingClientRect();return [b.left+scrollX,b.top+scrollY,b.width,b.height]})}"
    "document.body.setAttribute('data-rects',JSON.stringify(r));});</script>"
)
#: Keep the browser off the network while it renders.
_OFFLINE = ("--host-resolver-rules=MAP * ~NOTFOUND", "--disable-background-networking")


def _chromium(args: list[str], timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run(args, capture_output=True, timeout=timeout, stdin=subprocess.DEVNULL, check=False)


def _rects(chromium: str, page: Path, tmp: Path) -> dict:
    probe = tmp / "probe.html"
    probe.write_text(
        page.read_text(encoding="utf-8").replace("</body>", _PROBE + "</body>"), encoding="utf-8"
    )
    cmd = chromium_command(
        chromium, probe, tmp / "unused.png", tmp / "profile-probe", (1200, 900), extra=_OFFLINE
    )
    cmd = [c for c in cmd if not c.startswith("--screenshot")]
    cmd.insert(-1, "--dump-dom")
    dom = _chromium(cmd).stdout.decode("utf-8", "replace")
    found = re.search(r'data-rects="([^"]+)"', dom)
    assert found, dom[-500:]
    return json.loads(html.unescape(found.group(1)))


def _page_requests(netlog: Path) -> list[str]:
    """URLs the page itself asked the network for (not the browser's own background requests)."""
    log = json.loads(netlog.read_text(encoding="utf-8"))
    types = {v: k for k, v in log["constants"]["logEventTypes"].items()}
    out = []
    for e in log["events"]:
        p = e.get("params", {})
        if types.get(e["type"]) == "URL_REQUEST_START_JOB" and p.get("initiator") != "not an origin":
            if re.match(r"(https?|wss?|ftp)://", p.get("url", "")):
                out.append(p["url"])
    return out


def _shot(chromium: str, page: Path, png: Path, tmp: Path, size: tuple[int, int], netlog: Path) -> np.ndarray:
    from PIL import Image

    extra = (*_OFFLINE, f"--log-net-log={netlog}")
    cmd = chromium_command(chromium, page, png, tmp / f"profile-{png.stem}", size, extra=extra)
    done = _chromium(cmd)
    assert png.is_file(), done.stderr.decode("utf-8", "replace")[-800:]
    return np.asarray(Image.open(png).convert("RGB"), dtype=float)


def _crop(img: np.ndarray, rect: list[float]) -> np.ndarray:
    x, y, w, h = (int(round(v)) for v in rect)
    return img[y : y + h, x : x + w]


@pytest.mark.skipif(find_chromium() is None, reason="no chromium binary (apt-get install chromium)")
def test_report_renders_in_headless_chromium_and_asks_the_network_nothing(report):
    chromium = find_chromium()
    assert chromium is not None
    path, _, _ = report
    with tempfile.TemporaryDirectory(prefix="pkmtol-report-") as t:
        tmp = Path(t)
        # the check can fail: a page that fetches is seen fetching
        control = tmp / "control.html"
        control.write_text('<img src="http://pkmtol-probe.invalid/x.png"><p>x</p>', encoding="utf-8")
        _shot(chromium, control, tmp / "control.png", tmp, (400, 300), tmp / "control.json")
        assert _page_requests(tmp / "control.json") == ["http://pkmtol-probe.invalid/x.png"]
        rects = _rects(chromium, path, tmp)
        height = int(rects["height"]) + 20
        img = _shot(chromium, path, tmp / "report.png", tmp, (1200, height), tmp / "netlog.json")
        assert _page_requests(tmp / "netlog.json") == []
    assert img.shape == (height, 1200, 3)
    dark = np.all(img < 110, axis=-1)  # text
    not_white = np.any(np.abs(img - 255) > 30, axis=-1)
    # every table is drawn: text in it
    assert (
        len(rects["table"]) == 8
    )  # Table III, verification, contributions, stack-up, capability, drawing, claims, traditional
    for rect in rects["table"]:
        assert (
            dark[tuple(slice(int(a), int(a + b)) for a, b in ((rect[1], rect[3]), (rect[0], rect[2])))].mean()
            > 0.02
        )
    # every figure is drawn: ink, and its bars' colour (sensitivity, tolerances and contributions:
    # lengths #3b6fb6; the Δλ histogram: safe #2e9e4f), in the page's order
    assert len(rects["figure"]) == 4
    blue, green = np.array([0x3B, 0x6F, 0xB6]), np.array([0x2E, 0x9E, 0x4F])
    for rect, colour in zip(rects["figure"], (blue, blue, green, blue), strict=True):
        part = _crop(img, rect)
        assert np.any(np.abs(part - 255) > 30, axis=-1).mean() > 0.04
        assert (np.abs(part - colour).max(axis=-1) < 25).sum() > 300
    # the scene is drawn: not blank, the mechanism's orange legs near the middle of its frame
    (scene_rect,) = rects["scene"]
    scene = _crop(img, scene_rect)
    assert (
        scene.std() > 25 and not_white[int(scene_rect[1]) : int(scene_rect[1] + scene_rect[3])].mean() > 0.05
    )
    r, g, b = scene[..., 0], scene[..., 1], scene[..., 2]
    orange = (r > 60) & (r > 1.3 * g) & (g > 1.6 * b + 5)
    assert orange.sum() > 800
    ys, xs = np.nonzero(orange)
    h, w = orange.shape
    assert abs(xs.mean() / w - 0.5) < 0.15 and abs(ys.mean() / h - 0.5) < 0.2
