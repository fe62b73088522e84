"""Every colour a recording uses shows on the viewer's dark and light themes (studio/recording/colours.py)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from studio.recording import colours as c

RECORDING = Path(c.__file__).resolve().parent
THEMES = {"dark": c.DARK_BACKGROUND_RGB, "light": c.LIGHT_BACKGROUND_RGB}


def test_contrast_ratio_is_wcags():
    assert c.contrast_ratio((0, 0, 0), (255, 255, 255)) == pytest.approx(21.0)
    assert c.contrast_ratio((119, 119, 119), (255, 255, 255)) == pytest.approx(4.48, abs=0.01)
    assert c.contrast_ratio((128, 128, 128), (128, 128, 128)) == 1.0
    assert c.drawn_over((255, 255, 255, 0), (13, 13, 13)) == (13.0, 13.0, 13.0)


@pytest.mark.parametrize("theme", sorted(THEMES))
def test_every_recording_colour_shows_on_both_themes(theme):
    background = THEMES[theme]
    weak = []
    for role, rgba in c.recording_colours().items():
        opaque = rgba[3] == 255
        need = c.MIN_CONTRAST_OPAQUE if opaque else c.MIN_CONTRAST_TRANSLUCENT
        ratio = c.contrast_ratio(c.drawn_over(rgba, background), background)
        if ratio < need:
            weak.append(f"{role} {rgba}: {ratio:.2f} < {need}")
    assert not weak, f"colours that fade into the {theme} theme's background:\n" + "\n".join(weak)


def test_the_old_colours_would_have_failed():
    """The check can fail: the colours it replaced did (Tableau's gold on white, the faint
    inter-agent hairlines, the solve recording's light grey ground truth, the error scale's yellow)."""
    white, dark = c.LIGHT_BACKGROUND_RGB, c.DARK_BACKGROUND_RGB
    assert c.contrast_ratio((230, 185, 0), white) < c.MIN_CONTRAST_OPAQUE
    assert c.contrast_ratio((240, 200, 0), white) < c.MIN_CONTRAST_OPAQUE
    assert c.contrast_ratio((49, 54, 149), dark) < c.MIN_CONTRAST_OPAQUE
    for old in ((128, 128, 128, 60), (200, 200, 200, 160)):
        assert c.contrast_ratio(c.drawn_over(old, white), white) < c.MIN_CONTRAST_TRANSLUCENT


def test_the_recordings_take_their_colours_from_the_colours_module():
    """No colour literal elsewhere in studio/recording: a new colour goes into colours.py, and the
    contrast test above sees it."""
    literal = re.compile(r"\(\s*\d{1,3}\s*,\s*\d{1,3}\s*,\s*\d{1,3}\s*(,\s*\d{1,3}\s*)?\)")
    found = [
        f"{p.name}:{n}: {line.strip()}"
        for p in sorted(RECORDING.glob("*.py"))
        if p.name != "colours.py"
        for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), start=1)
        if literal.search(line)
    ]
    assert not found, "\n".join(found)


def test_recordings_use_the_listed_colours():
    from studio.recording.dataset import agent_colour, inter_style
    from studio.recording.evaluation import error_colours

    listed = set(c.recording_colours().values())
    assert {agent_colour(k) for k in range(10)} <= listed
    assert {inter_style(10)[0], inter_style(10**6)[0]} <= listed
    for t in np.linspace(0.0, 1.0, 41):
        r, g, b, a = (int(v) for v in error_colours(np.array([t]), 1.0)[0])
        assert (r, g, b, a) in listed
