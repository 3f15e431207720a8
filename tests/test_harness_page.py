"""harness.core.page: the one page writer (report, regress and study pages)."""

from __future__ import annotations

from harness.core import page


def _png(path):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"\x89PNG\r\n\x1a\n")
    return path


def test_write_page_sections_and_links(tmp_path):
    img = _png(tmp_path / "img" / "x.png")
    out = page.write_page(tmp_path / "rep" / "index.html", "T <1>", [
        page.Section("First part", [{"a": 1.5, "ok": True, "map": img}], notes="n1\n\nn2", anchor="first"),
        page.Section("Second", [{"b": "x"}], images=[("fig", img)]),
    ], notes="top")
    html = out.read_text()
    assert "T &lt;1&gt;" in html and '<h2 id="first">First part</h2>' in html and 'href="#second"' in html
    assert html.count("<table>") == 2 and 'src="../img/x.png"' in html and "pass" in html
    assert html.count('<p class="note">') == 3
    assert html.count("<style>") == 1 and page.STYLE.strip() in html


def test_text_is_escaped_markup_is_not(tmp_path):
    out = page.write_page(tmp_path / "p.html", "t", [page.Section(
        "s", [{"text": "<b>", "markup": page.bold("x & y"), "cell": page.Cell("<i>", "fail")}],
        body=[page.pre("a < b"), page.bullets(["1 < 2", page.code("c")])])])
    html = out.read_text()
    assert "<td class=\"text\">&lt;b&gt;</td>" in html
    assert "<b>x &amp; y</b>" in html
    assert '<td class="text fail">&lt;i&gt;</td>' in html
    assert "<pre>a &lt; b</pre>" in html and "<li>1 &lt; 2</li><li><code>c</code></li>" in html


def test_status_badge_and_no_contents_for_one_section(tmp_path):
    html = page.write_page(tmp_path / "p.html", "t", [page.Section("only", status=page.Cell("FAIL", "fail"))]).read_text()
    assert '<span class="badge fail">FAIL</span>' in html
    assert "<ul>" not in html  # one section: no contents list


def test_cells(tmp_path):
    assert page.format_cell(0.123456, None) == ("0.1235", "")
    assert page.format_cell(False, None) == ("FAIL", "text fail")
    assert page.format_cell(None, None) == ("", "")
    text, cls = page.format_cell(_png(tmp_path / "a.png"), tmp_path)
    assert cls == "img" and 'href="a.png"' in text


def test_slug():
    assert page.slug("Dipole subsurface vs stock (x)") == "dipole-subsurface-vs-stock-x"
    assert page.slug("???") == "x"
