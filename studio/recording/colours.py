"""Every colour the studio's recordings use, defined once, and the contrast rule they follow.

A recording is opened on the viewer's dark theme or on its light theme (the web viewer follows the
operating system's preference), so each colour must show on both backgrounds. The rule, checked by
``tests/recording/test_colours.py`` for every colour listed in :func:`recording_colours`:

* an opaque colour has a WCAG 2 contrast ratio of at least :data:`MIN_CONTRAST_OPAQUE` (2.0)
  against both backgrounds;
* a translucent colour (the initial estimate, the inter-agent loop closures), composited over the
  background at its alpha as one line of it is drawn, at least :data:`MIN_CONTRAST_TRANSLUCENT` (1.5):
  quieter than the opaque marks by design, never gone.

The backgrounds are Rerun 0.41's: see :data:`DARK_BACKGROUND_RGB`. Why these thresholds (and not
WCAG's 3:1 for graphics) is in docs/recordings.md, "Colours on the dark and the light theme".
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "AGENT_PALETTE_RGB",
    "INITIAL_ALPHA",
    "INTER_RGB",
    "INTER_ALPHA",
    "INTER_FAINT_RGB",
    "INTER_FAINT_ALPHA",
    "INTER_DENSITY_RGBA",
    "OUTLIER_COLOUR",
    "GROUND_TRUTH_GREY",
    "ERROR_SCALE_RGB",
    "SOLVE_ESTIMATE_ALPHA",
    "error_colours",
    "REPLAY_LINK_COLOUR",
    "DARK_BACKGROUND_RGB",
    "LIGHT_BACKGROUND_RGB",
    "MIN_CONTRAST_OPAQUE",
    "MIN_CONTRAST_TRANSLUCENT",
    "relative_luminance",
    "contrast_ratio",
    "drawn_over",
    "recording_colours",
]

RGB = tuple[int, int, int]
RGBA = tuple[int, int, int, int]

#: Agent colours: Tableau 10 with its grey replaced by a gold (grey is the inter-agent closures'),
#: and its three lightest hues (gold, olive, cyan) darkened to show on the light theme's white.
AGENT_PALETTE_RGB: tuple[RGB, ...] = (
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (195, 155, 0),
    (160, 160, 20),
    (20, 175, 190),
)
#: The initial estimate (dead reckoning): the agent's hue at this alpha (the ground truth is opaque).
INITIAL_ALPHA = 120
#: Inter-agent loop closures: a mid grey, no agent's colour.
INTER_RGB: RGB = (128, 128, 128)
INTER_ALPHA = 200
#: Inter-agent loop closures when there are many (thin hairlines that add up where they crowd).
INTER_FAINT_RGB: RGB = (120, 120, 120)
INTER_FAINT_ALPHA = 100
#: The inter-agent loop-closure density (many closures): a light grey, opaque (over the agents' paths).
INTER_DENSITY_RGBA: RGBA = (175, 175, 175, 255)
#: Outlier loop closures (``outliers.txt``): magenta, no agent's colour.
OUTLIER_COLOUR: RGBA = (255, 0, 200, 255)
#: Ground truth under an estimate (evaluation and solve recordings): a grey on no error scale.
GROUND_TRUTH_GREY: RGBA = (150, 150, 150, 255)
#: Error scale of evaluation and solve recordings, from no error to the largest shown: viridis
#: (perceptually uniform, readable with every common colour-vision deficiency) sampled at t = 0.18,
#: 0.32, 0.46, 0.60, 0.74 (matplotlib's table): the stretch of it that keeps the contrast rule on
#: both themes (its darkest purple vanishes on the dark theme, its yellow on white).
ERROR_SCALE_RGB: tuple[RGB, ...] = ((67, 62, 133), (50, 100, 142), (36, 134, 142), (34, 168, 132), (88, 199, 101))
#: Solve recordings: each agent's estimate path is drawn in its agent colour at this alpha.
SOLVE_ESTIMATE_ALPHA = 200

#: Background of the viewer's views on the dark theme: Rerun 0.41's design token
#: ``viewport_background`` of ``crates/viewer/re_ui/data/dark_theme.ron`` (``{Gray.100}``, ``#0d0d0d``
#: in ``color_table.ron``; both files are embedded in the ``rerun`` executable of rerun-sdk 0.41, where
#: they were read). Time-series plots fall back to the same token (``PlotBackground``,
#: ``re_component_fallbacks/src/blueprint_component_fallbacks.rs``), and so does the 3D view:
#: ``studio snapshot`` of a recording on the dark theme shows a uniform ``(13, 13, 13)`` behind the data.
DARK_BACKGROUND_RGB: RGB = (13, 13, 13)
#: The same token on the light theme: ``light_theme.ron``'s ``viewport_background``, ``{Gray.1000}``,
#: ``#ffffff``.
LIGHT_BACKGROUND_RGB: RGB = (255, 255, 255)

MIN_CONTRAST_OPAQUE = 2.0
MIN_CONTRAST_TRANSLUCENT = 1.5


def relative_luminance(rgb: tuple[float, ...]) -> float:
    """WCAG 2 relative luminance of an sRGB colour given as 0-255 values (alpha ignored)."""
    c = np.asarray(rgb[:3], dtype=np.float64) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return float(lin @ np.array([0.2126, 0.7152, 0.0722]))


def contrast_ratio(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    """WCAG 2 contrast ratio of two sRGB colours, 1 (none) to 21 (black on white)."""
    la, lb = relative_luminance(a), relative_luminance(b)
    return (max(la, lb) + 0.05) / (min(la, lb) + 0.05)


def drawn_over(rgba: tuple[int, ...], background: RGB) -> tuple[float, float, float]:
    """The colour one mark of ``rgba`` shows over ``background`` (alpha blending in sRGB, as the
    viewer blends)."""
    alpha = rgba[3] / 255.0 if len(rgba) == 4 else 1.0
    return tuple(float(alpha * c + (1.0 - alpha) * b) for c, b in zip(rgba[:3], background))  # type: ignore[return-value]


#: Links between robots in contact (studio replay): a dark orange, no agent's hue.
REPLAY_LINK_COLOUR: RGBA = (214, 120, 0, 255)


def recording_colours() -> dict[str, RGBA]:
    """Every colour a recording can hold, by role: what the contrast test checks. The evaluation's
    error scale is sampled between its stops as :func:`studio.recording.evaluation.error_colours`
    interpolates it."""
    out: dict[str, RGBA] = {}
    for k, (r, g, b) in enumerate(AGENT_PALETTE_RGB):
        out[f"agent {k + 1}"] = (r, g, b, 255)
        out[f"agent {k + 1} initial estimate"] = (r, g, b, INITIAL_ALPHA)
    out["inter-agent loop closures"] = (*INTER_RGB, INTER_ALPHA)
    out["inter-agent loop closures, many"] = (*INTER_FAINT_RGB, INTER_FAINT_ALPHA)
    out["inter-agent count plot"] = (*INTER_RGB, 255)
    out["inter-agent loop-closure density"] = INTER_DENSITY_RGBA
    out["outlier loop closures"] = OUTLIER_COLOUR
    out["ground truth (evaluation, solve)"] = GROUND_TRUTH_GREY
    scale = np.asarray(ERROR_SCALE_RGB, dtype=np.float64)
    for t in np.linspace(0.0, 1.0, 41):
        x = t * (len(scale) - 1)
        lo = min(int(np.floor(x)), len(scale) - 2)
        r, g, b = (int(v) for v in np.rint(scale[lo] * (1.0 - (x - lo)) + scale[lo + 1] * (x - lo)))
        out[f"error scale at {t:.3f}"] = (r, g, b, 255)
    for k, (r, g, b) in enumerate(AGENT_PALETTE_RGB):
        out[f"agent {k + 1} solve estimate path"] = (r, g, b, SOLVE_ESTIMATE_ALPHA)
    out["replay links"] = REPLAY_LINK_COLOUR
    return out


def error_colours(errors: np.ndarray, largest: float) -> np.ndarray:
    """(n, 4) uint8 RGBA colours of ``errors`` on the error scale 0 .. ``largest`` (clipped above)."""
    scale = np.asarray(ERROR_SCALE_RGB, dtype=np.float64)
    t = np.clip(np.asarray(errors, dtype=np.float64) / (largest if largest > 0 else 1.0), 0.0, 1.0)
    x = t * (len(scale) - 1)
    lo = np.minimum(np.floor(x).astype(np.int64), len(scale) - 2)
    f = (x - lo)[:, None]
    rgb = np.rint(scale[lo] * (1.0 - f) + scale[lo + 1] * f).astype(np.uint8)
    return np.column_stack([rgb, np.full(len(rgb), 255, dtype=np.uint8)])
