"""Constants and shared defaults, each defined once (names carry their units)."""

from __future__ import annotations

__all__ = [
    "NS_PER_S",
    "DEFAULT_MAX_MEMORY_GB",
    "DEFAULT_MAX_OUTPUT_GB",
    "MAX_MAGNITUDE",
    "MIN_MAGNITUDE",
    "MAX_RECORDED_COORDINATE_M",
    "MAX_SOLUTION_M",
    "CHI2_RISE_TOLERANCE",
    "MAX_SPLIT_ROBOTS",
    "MAX_STAMP_S",
    "QUAT_NORM_TOLERANCE",
]

#: Nanoseconds per second: timestamps are int64 nanoseconds inside the studio.
NS_PER_S = 1_000_000_000

#: Default memory limit [GB] of the commands that estimate their memory before working.
DEFAULT_MAX_MEMORY_GB = 8.0
#: Default limit [GB] of what ``studio synth`` may write.
DEFAULT_MAX_OUTPUT_GB = 20.0

#: Largest magnitude of any number the studio accepts from a user or an input file, in that number's
#: own unit: a coordinate, length, radius or standard deviation [m], a time [s], a limit, a scale.
#: Beyond it squares and products overflow the generator's, graph builder's and optimizers' float64
#: maths, and it is a typo rather than a request (UTM and ECEF coordinates stay under 1e7 m;
#: kollagen's paper configs use values under 10). One bound for all of them, so it carries no unit.
MAX_MAGNITUDE = 1e9
#: Smallest positive value of such a number (``--lc-radius 1e-300``, a stepsize): below it squares
#: underflow and the computations it feeds divide by zero.
MIN_MAGNITUDE = 1e-9
#: Largest coordinate [m] a recording draws (``studio record``/``view``, any multi-g2o folder, also one
#: the studio did not write): squares of positions overflow float64 in the viewer's maths beyond it.
#: Wider than :data:`MAX_MAGNITUDE`, because it bounds only what the recording computes.
MAX_RECORDED_COORDINATE_M = 1e12
#: Largest coordinate [m] an optimizer's answer may have (inputs are held to :data:`MAX_MAGNITUDE`;
#: an answer 1000 times farther is a diverged optimizer, e.g. an external command printing 1e300).
MAX_SOLUTION_M = 1e12
#: Relative rise of chi2 over a solve tolerated as rounding (this fraction of the start, plus as much).
CHI2_RISE_TOLERANCE = 1e-9
#: Most robots ``--split`` cuts one trajectory or graph into (synth's limit of agents, too).
MAX_SPLIT_ROBOTS = 10_000
#: Largest time [s] whose nanoseconds fit int64 (about 292 years): a time in seconds beyond it
#: cannot become a stamp.
MAX_STAMP_S = ((1 << 63) - 1) / 1e9 * (1 - 1e-12)

#: How far from unit length a quaternion read from a file may be and still be normalised (g2o, GTSAM
#: and SE-Sync normalise; files written with six decimals, SE-Sync's ``cubicle.g2o``, are off by up to
#: 1.7e-6). Farther is a broken file, refused.
QUAT_NORM_TOLERANCE = 1e-5
