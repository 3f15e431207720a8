"""harness.core.runner: statistics parsing, error reporting, parallel jobs, file staging."""

from __future__ import annotations

import numpy as np
import pytest

from harness.core import runner
from harness.core.scenes import DistantLight, SphereScene

STATS = """\
----------------------------------------------------------------------------
Parser Time
  Parse Time:       0 hours  0 minutes  2 seconds (2.250 seconds)
              using 1 thread(s) with 2.249 CPU-seconds total
  Bounding Time:    0 hours  0 minutes  0 seconds (0.004 seconds)
              using 1 thread(s) with 0.003 CPU-seconds total
----------------------------------------------------------------------------
Pixels:            65536   Samples:               0   Smpls/Pxl: 0.00
Rays:              65536   Saved:                 0   Max Level: 1/5
Shadow Ray Tests:    40000   Succeeded:                   123
Peak memory used:          12345678 bytes
----------------------------------------------------------------------------
Render Time:
  Photon Time:      No photons
  Radiosity Time:   No radiosity
  Trace Time:       1 hours  2 minutes  3 seconds (3723.456 seconds)
              using 4 thread(s) with 14000.125 CPU-seconds total
POV-Ray finished
"""


def test_parse_stats_canned():
    st = runner.parse_stats(STATS)
    assert st["parse_time"] == 2.25 and st["parse_cpu_time"] == 2.249
    assert st["bounding_time"] == 0.004
    assert st["trace_time"] == 3723.456
    assert st["trace_threads"] == 4 and st["trace_cpu_time"] == 14000.125
    assert st["pixels"] == 65536 and st["rays"] == 65536
    assert st["shadow_ray_tests"] == 40000 and st["shadow_rays_succeeded"] == 123
    assert st["peak_memory_bytes"] == 12345678
    assert "photon_time" not in st and "radiosity_time" not in st


def test_parse_stats_without_decimal_figure():
    st = runner.parse_stats("  Trace Time:       0 hours  1 minutes  5 seconds\n")
    assert st["trace_time"] == 65.0


def test_render_reports_trace_time(stock):
    s = SphereScene(lights=(DistantLight(30, 0),), finish={"diffuse": 0.6, "phong": 0.5},
                    width=160, height=160)
    res = runner.render(s, stock)
    assert res.trace_seconds is not None and res.parse_seconds is not None
    assert 0.0 <= res.trace_seconds < res.wall_seconds
    assert res.stats["pixels"] == 160 * 160
    assert res.stats["trace_threads"] == 1
    assert res.image.shape == (160, 160, 3) and res.image.dtype == np.float32
    assert res.exr_dtype == np.float16  # stock writes half even when asked for float
    assert "+FE" in res.command and "-A" in res.command


def test_stock_never_gets_fe32(stock):
    cmd = runner.build_command(stock, 8, 8, float_exr=True)
    assert "+FE" in cmd and "+FE32" not in cmd


BROKEN = """#version 3.7;
global_settings { assumed_gamma 1.0 }
sphere { 0, 1
  pigment { rgb 1 }
  finish { diffsue 0.5 }
}
"""


def test_broken_scene_raises_with_line(stock):
    with pytest.raises(runner.RenderError) as ei:
        runner.render(BROKEN, stock, width=8, height=8)
    e = ei.value
    assert e.line == 5 and e.file == runner.SCENE_NAME
    assert "diffsue" in e.message and "line 5" in str(e)
    assert e.returncode != 0 and "Parse Error" in e.stderr


def test_missing_include_raises(stock):
    text = '#version 3.7;\n#include "no_such_file.inc"\n'
    with pytest.raises(runner.RenderError) as ei:
        runner.render(text, stock, width=8, height=8)
    assert ei.value.line == 2 and "no_such_file.inc" in ei.value.message


def test_warnings_are_collected(stock):
    text = '#version 3.7;\n#warning "harness test"\n'
    res = runner.render(text, stock, width=4, height=4)
    assert any("harness test" in w and "line 2" in w for w in res.warnings)
    assert np.all(res.image == 0.0)


def test_standard_includes_and_staged_files(stock, tmp_path):
    inc = tmp_path / "mine.inc"
    inc.write_text("#declare Grey = 0.25;\n")
    text = ('#version 3.7;\n#include "colors.inc"\n#include "mine.inc"\n'
            "global_settings { assumed_gamma 1.0 }\n"
            "background { rgb Grey }\n")
    res = runner.render(text, stock, width=4, height=4, files={"mine.inc": inc})
    assert np.all(res.image == 0.25)


def test_render_many_in_order_with_failures(stock):
    scenes = [SphereScene(lights=(DistantLight(t, 0),), width=16, height=16) for t in (0, 60)]
    jobs = [runner.RenderJob(scenes[0]), runner.RenderJob(BROKEN, {"width": 8, "height": 8}),
            runner.RenderJob(scenes[1])]
    out = runner.render_many(jobs, binary=stock, max_workers=2, return_exceptions=True)
    assert isinstance(out[1], runner.RenderError)
    assert out[0].image[8, 8, 0] > out[2].image[8, 8, 0] > 0  # 60 deg light is dimmer at the centre
    with pytest.raises(runner.RenderError):
        runner.render_many(jobs, binary=stock, max_workers=2, progress=False)


def test_workdir_is_kept(stock, tmp_path):
    runner.render(SphereScene(width=8, height=8), stock, workdir=tmp_path / "job")
    assert (tmp_path / "job" / runner.SCENE_NAME).is_file()
    assert (tmp_path / "job" / runner.OUTPUT_NAME).is_file()
