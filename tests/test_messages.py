"""Messages that suggest: a misspelt keyword, declared name or preset gets "did you mean", a
message carries one prefix, and notes about a medium come only for the media a scene uses,
naming the medium, where it was written and the channel.

The suggestion is shading::did_you_mean (core/suggest.h; unit tests in suggest_test.cpp) over
POV's keywords and the declared names in scope (patch 0019) or the media presets; the notes are
FinishModel::notes, said by the parser after the symbol table is gone (patch 0006).
"""

from __future__ import annotations

import pytest

from harness.core import runner

SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
{include}
camera {{ location -3*z look_at 0 }}
light_source {{ <-3, 4, -5> rgb 1 }}
sphere {{ 0, 1 pigment {{ rgb 1 }} finish {{ {finish} }} }}
"""


def render(finish, include=""):
    return runner.render(SCENE.format(finish=finish, include=include), "fork", width=8, height=8)


def error(finish, include=""):
    with pytest.raises(runner.RenderError) as e:
        render(finish, include)
    assert (e.value.file, e.value.line) == ("scene.pov", 6), e.value.message
    return " ".join(e.value.message.split())


@pytest.mark.parametrize("finish, include, expect", [
    ('brdf_tabel { "gold.brdf" }', "", "undeclared identifier 'brdf_tabel' found instead; did you mean 'brdf_table'?"),
    ('brdf_modle { "lambert" }', "", "did you mean 'brdf_model'?"),
    ("F_Dipole_Marbel", '#include "dipole_media.inc"', "undeclared identifier 'F_Dipole_Marbel' found instead; did you mean 'F_Dipole_Marble'?"),
    ('dipole { "Marbel" }', "", "unknown medium 'Marbel'; did you mean 'Marble'? Known: 'Apple'"),
])
def test_a_misspelt_name_gets_the_one_meant(finish, include, expect):
    assert expect in error(finish, include)


def test_no_suggestion_when_nothing_is_close():
    msg = error("qwertyuiop 1")
    assert "undeclared identifier 'qwertyuiop' found instead" in msg and "did you mean" not in msg, msg
    msg = error('dipole { "Zzzzz" }')
    assert "unknown medium 'Zzzzz'; known: 'Apple'" in msg and "did you mean" not in msg, msg


def test_one_prefix_per_message():
    msg = error("dipole { sigma_s_prime 1 sigma_a -0.01 }")
    assert "Parse Error: dipole medium: sigma_a.r = -0.01: expected a finite value >= 0 (1/mm)" in msg, msg
    assert "dipole: dipole" not in msg


def test_an_include_of_every_medium_says_nothing_about_the_unused_ones():
    r = render("diffuse 0.6", '#include "dipole_media.inc"')
    assert not [w for w in r.warnings if "dipole" in w], r.warnings


def test_a_note_names_the_medium_where_it_was_written_and_the_channel():
    # Coke's g is 0.965 (r) and 0.972 (g): beyond the exact profile's tables, one note each
    r = render("F_Dipole_Coke", '#include "dipole_media.inc"')
    notes = [" ".join(w.split()) for w in r.warnings if "outside the exact profile" in w]
    assert len(notes) == 2, r.warnings
    # POV's own form: "File 'dipole_media.inc' line N: Parse Warning: ..." at the block
    assert "dipole_media.inc line " in notes[0].split(":")[0], notes
    assert "Parse Warning: dipole medium 'Coke': g = 0.965 (r) is outside the exact profile's tables [0, 0.95]" in notes[0], notes
    assert "g = 0.972 (g) is outside" in notes[1], notes


GLOSSY_SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ location -3*z look_at 0 }}
light_source {{ <-3, 4, -5> rgb 1 area_light x, y, 4, 4 {adaptive} }}
sphere {{ 0, 1 finish {{ brdf_model {{ "microfacet d=beckmann m=0.2" samples 4 }} }} }}
plane {{ y, -1 pigment {{ rgb 0.5 }} }}
"""


@pytest.mark.parametrize("adaptive, advice", [
    ("", "Lower 'samples', make area lights 'adaptive', or expect"),
    ("adaptive 1", "Lower 'samples' or the area light's 'adaptive' level, or expect"),
])
def test_the_glossy_cost_warning_names_no_line_and_fits_the_light(adaptive, advice):
    # Said once parsing is done, of the scene as a whole: the line parsing ended on (the
    # plane's, here) is not its cause, so none is named; a light that is already adaptive is
    # not told to become so.
    r = runner.render(GLOSSY_SCENE.format(adaptive=adaptive), "fork", width=8, height=8)
    text = " ".join(r.stderr.split())
    assert ("Parse Warning: Glossy reflection: a finish with 'samples 4' traces 4 glossy rays per hit" in text
            and "up to 64 shadow rays per hit" in text), text
    assert not [w for w in r.warnings if "Glossy reflection" in w], r.warnings
    assert advice in text, text
    assert ("4 x 4, adaptive)" in text) == bool(adaptive), text
