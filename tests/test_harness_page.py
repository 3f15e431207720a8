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
    assert page.format_cell(0.123456, None) == ("0.1235", "num")  # td.num: never wraps
    assert page.format_cell(12, None) == ("12", "num")
    assert page.format_cell(False, None) == ("FAIL", "text fail")
    assert page.format_cell(None, None) == ("", "")
    text, cls = page.format_cell(_png(tmp_path / "a.png"), tmp_path)
    assert cls == "img" and 'href="a.png"' in text


def test_slug():
    assert page.slug("Dipole subsurface vs stock (x)") == "dipole-subsurface-vs-stock-x"
    assert page.slug("???") == "x"


def test_numbers_in_text_do_not_break(tmp_path):
    # "2.757e-08" broke after its minus sign in a narrow column (issue 33): number-like words
    # of text cells are kept on one line, the rest still wraps
    text, cls = page.format_cell("rel 2.757e-08 of <1e-4>", None)
    assert cls == "text"
    assert text == ('rel <span class="nw">2.757e-08</span> of <span class="nw">&lt;1e-4&gt;</span>')
    assert "td.num, span.nw { white-space: nowrap; }" in page.STYLE


def test_plots_are_shown_at_natural_size(tmp_path):
    from harness.core import plotting

    plt = plotting.pyplot()
    fig, ax = plt.subplots(figsize=(2, 1))
    ax.plot([0, 1], [0, 1])
    fig_png = plotting.save(fig, tmp_path / "fig.png")
    render = _png(tmp_path / "render.png")
    assert page.is_plot(fig_png) and not page.is_plot(render)
    text, _ = page.format_cell(fig_png, tmp_path)
    assert '<div class="plotbox">' in text and 'class="plot"' in text and "width=" not in text
    text, _ = page.format_cell(render, tmp_path)
    assert 'class="thumb"' in text
    html = page.write_page(tmp_path / "p.html", "t", [page.Section("s", images=[("cap", fig_png)])]).read_text()
    assert 'class="plot"' in html
