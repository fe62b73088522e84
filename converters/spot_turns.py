"""Turns on the spot read from the tracked point's motion while the robot stands (the ``turns``
heading method; pure numpy).

Positions cannot show a turn on the spot when the tracked point sits on the turning axis. A real
robot's tracked point rarely does: on UTIAS MR.CLAM's iRobot Creates the Vicon point sits a few
millimetres off the axis and creeps while the robot turns (backwards while it turns clockwise). Seen
from the robot, the point then moves in a way that depends on how the robot turns, and seen from the
world that motion turns with the robot. This module learns those signatures from the path itself and
decodes each stop's turning from them.

The model of a stop, in bins of :data:`STOP_BIN_S`: a hidden heading on a grid of
:data:`HEADING_CELLS` cells and a turning state, one of :data:`TURN_RATES_RAD_S` (standing, turning
either way at two rates, creeping forward). The heading moves by the state's rate with a random walk
of :data:`HEADING_NOISE_RAD_PER_SQRT_S`, and a state lasts :data:`STATE_DWELL_S` on average. The
point's displacement in a bin, turned into the body frame of the heading, is normal about the state's
signature. A signature is the point's mean velocity in the body frame: ``rate * (-p_y, p_x)`` for a
point at ``(p_x, p_y)`` from the axis, plus a creep along the body axis for each direction of turn,
and its spread.

The signatures are learned by expectation-maximisation over all of a path's stops, starting from none
(:data:`EM_ITERATIONS` rounds). Each stop is then decoded by forward-backward. It starts at the
heading before the stop and ends, softly (:data:`END_SIGMA_RAD`), at the heading after it, on any
multiple of a full turn. A stop is decoded only where the signatures explain its motion better, by
:data:`GATE_NATS`, than the same motion with no direction. A point on the axis, or one that only
jitters, shows no signature, and its stops keep the ``smoothed`` method's even turn. Where a stop is
decoded, the heading is taken halfway (:data:`BLEND`) from that even turn to the decoded one. If the
decoding ends on another multiple of a full turn, it goes from a turn even in time to that end.

Measured on real paths (docs/converters.md; the correlation of the yaw increments, every 0.5 s, with
the true ones): MR.CLAM datasets 6 and 7, ten robots, 0.806-0.926 (``smoothed``: 0.734-0.927), and
KITTI 00 unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from studio.core.units import NS_PER_S

__all__ = ["decode_spot_turns"]

STOP_BIN_S = 0.25
"""Length [s] of the bins a stop is cut into."""
HEADING_CELLS = 256
"""Cells of the heading grid (1.4 degrees each)."""
HEADING_NOISE_RAD_PER_SQRT_S = 0.1
"""Random walk of the heading about its state's rate [rad / sqrt(s)]."""
STATE_DWELL_S = 1.2
"""Mean time [s] in one turning state."""
END_SIGMA_RAD = 0.15
"""Spread [rad] of the heading after the stop, as the decoder's end."""
START_SIGMA_RAD = 0.03
"""Spread [rad] of the heading before the stop, as the decoder's start."""
MIN_STOP_S = 1.5
"""Stops shorter than this [s] are not decoded."""
GATE_NATS = 3.0
"""How much better [nats] the signatures must explain a stop's motion than a motion with no
direction, for the stop to be decoded."""
EM_ITERATIONS = 6
"""Rounds of expectation-maximisation that learn a path's signatures."""
SPREAD_FLOOR_MPS = 0.6e-3
"""Smallest spread [m/s] of a signature."""
OUTLIER_SIGMAS = 6.0
"""A bin's motion farther than this many spreads from a state's signature counts as that far (a jump
of the tracking tells nothing of the heading)."""
EMISSION_WEIGHT = 0.5
"""Weight of the motion's log-likelihood (the normal model of a bin's motion is overconfident)."""
BLEND = 0.5
"""Part of the way from the even turn to the decoded one."""
TURN_RATES_RAD_S = np.array([0.0, -0.2, 0.2, -0.5, 0.5, 0.0])
"""The states' turn rates [rad/s]: standing, clockwise and anticlockwise at two rates, creeping
forward (the last; its motion along the body axis)."""
_INITIAL_SPREAD_MPS = np.array([1e-3, 2e-3, 2e-3, 3e-3, 3e-3, 20e-3])
_INITIAL_FORWARD_MPS = 30e-3


@dataclass(frozen=True)
class _Signatures:
    """Per state: the point's mean velocity in the body frame (``forward + 1j * left``, m/s) and its
    spreads along and across the body axis (m/s). ``directionless``: the null model, the same sizes
    with no direction (the heading does not matter)."""

    mean_mps: np.ndarray
    spread_forward_mps: np.ndarray
    spread_left_mps: np.ndarray
    directionless: bool = False


def _grid() -> np.ndarray:
    return np.arange(HEADING_CELLS) * (2 * np.pi / HEADING_CELLS)


def _heading_kernels(dt_s: float) -> np.ndarray:
    """Per state, the Fourier transform of the heading's move over one bin (a wrapped normal about
    the state's turn)."""
    offset = np.angle(np.exp(1j * (_grid()[:, None] - TURN_RATES_RAD_S[None, :] * dt_s)))
    k = np.exp(-0.5 * offset**2 / (HEADING_NOISE_RAD_PER_SQRT_S**2 * dt_s))
    k /= k.sum(axis=0)
    kernels: np.ndarray = np.fft.fft(k, axis=0)
    return kernels


def _log_emission(body: np.ndarray, disp: np.ndarray, dt_s: float, sig: _Signatures) -> np.ndarray:
    """``(n, cells, states)``: log-likelihood of each bin's motion (``body``: its displacement in the
    body frame of every grid heading) in each state."""
    if sig.directionless:  # the motion's size only, isotropic
        r2 = np.abs(disp / dt_s) ** 2
        s2 = (np.abs(sig.mean_mps) ** 2 + sig.spread_forward_mps**2 + sig.spread_left_mps**2) / 2
        ll = -0.5 * r2[:, None] / s2[None, :] - np.log(s2)[None, :]
        return np.repeat(ll[:, None, :], HEADING_CELLS, axis=1)
    v = body / dt_s
    f = (v.real[:, :, None] - sig.mean_mps.real[None, None, :]) / sig.spread_forward_mps
    le = (v.imag[:, :, None] - sig.mean_mps.imag[None, None, :]) / sig.spread_left_mps
    # beyond OUTLIER_SIGMAS the bin says nothing of the heading (a jump of the tracking, not a turn)
    d2 = np.minimum(f**2 + le**2, OUTLIER_SIGMAS**2)
    out: np.ndarray = -0.5 * d2 - np.log(sig.spread_forward_mps * sig.spread_left_mps)
    return out


def _forward_backward(
    disp: np.ndarray, dt_s: float, start_rad: float, end_rad: float, sig: _Signatures
) -> tuple[np.ndarray, np.ndarray, float]:
    """One stop: the posterior ``(n, cells, states)`` of each bin's heading and state, the bins'
    displacements in the body frame of every grid heading, and the log-likelihood of the stop. (No
    probability underflows: a bin's log-likelihood is bounded below, see :data:`OUTLIER_SIGMAS`.)"""
    n, states = len(disp), len(TURN_RATES_RAD_S)
    grid = _grid()
    body = disp[:, None] * np.exp(-1j * grid[None, :])
    ll = EMISSION_WEIGHT * _log_emission(body, disp, dt_s, sig)
    top = ll.max(axis=(1, 2), keepdims=True)
    emission = np.exp(ll - top)
    stay = np.exp(-dt_s / STATE_DWELL_S)
    trans = np.full((states, states), (1 - stay) / (states - 1))
    np.fill_diagonal(trans, stay)
    kern = _heading_kernels(dt_s)
    alpha = np.empty((n, HEADING_CELLS, states))
    log_z = float(top.sum())
    start = np.exp(-0.5 * (np.angle(np.exp(1j * (grid - start_rad))) / START_SIGMA_RAD) ** 2)
    prev = (start / start.sum())[:, None] * np.full(states, 1.0 / states)[None, :]
    for k in range(n):
        pred = np.maximum(np.real(np.fft.ifft(np.fft.fft(prev @ trans, axis=0) * kern, axis=0)), 0.0)
        a = pred * emission[k]
        z = a.sum()
        log_z += float(np.log(z))
        alpha[k] = a / z
        prev = alpha[k]
    end = np.exp(-0.5 * (np.angle(np.exp(1j * (grid - end_rad))) / END_SIGMA_RAD) ** 2)
    beta = np.empty_like(alpha)
    beta[-1] = end[:, None]
    z_end = (alpha[-1] * beta[-1]).sum()
    log_z += float(np.log(z_end))
    beta[-1] /= z_end
    for k in range(n - 2, -1, -1):
        x = emission[k + 1] * beta[k + 1]
        back = np.maximum(np.real(np.fft.ifft(np.fft.fft(x, axis=0) * np.conj(kern), axis=0)), 0.0)
        bk = back @ trans.T
        beta[k] = bk / bk.max()
    gamma = alpha * beta
    gamma /= gamma.sum(axis=(1, 2), keepdims=True)
    return gamma, body, log_z


def _learn(stats: list[tuple[np.ndarray, np.ndarray, float]], sig: _Signatures) -> _Signatures:
    """The maximisation step: each state's mean and spreads from the posteriors, the means then
    held to their structure (the point's offset from the axis shared by the turning states, a creep
    along the body axis per direction of turn; no motion while standing)."""
    states = len(TURN_RATES_RAD_S)
    weight = np.zeros(states)
    total = np.zeros(states, dtype=complex)
    for gamma, body, dt_s in stats:
        weight += gamma.sum(axis=(0, 1))
        total += np.einsum("ngs,ng->s", gamma, body / dt_s)
    mean = np.where(weight > 1e-6, total / np.maximum(weight, 1e-12), sig.mean_mps)
    var_f, var_l = np.zeros(states), np.zeros(states)
    for gamma, body, dt_s in stats:
        v = body / dt_s
        var_f += np.einsum("ngs,ngs->s", gamma, (v.real[:, :, None] - mean.real[None, None, :]) ** 2)
        var_l += np.einsum("ngs,ngs->s", gamma, (v.imag[:, :, None] - mean.imag[None, None, :]) ** 2)
    sf = np.where(weight > 1, np.sqrt(var_f / np.maximum(weight, 1e-12)), sig.spread_forward_mps)
    sl = np.where(weight > 1, np.sqrt(var_l / np.maximum(weight, 1e-12)), sig.spread_left_mps)
    rate = TURN_RATES_RAD_S
    turning = rate != 0
    w_f = weight / np.maximum(sf, SPREAD_FLOOR_MPS) ** 2
    w_l = weight / np.maximum(sl, SPREAD_FLOOR_MPS) ** 2
    # across the body: rate * p_x, one offset for all turning states (weighted least squares)
    p_x = float((w_l * rate * mean.imag)[turning].sum() / max((w_l * rate**2)[turning].sum(), 1e-12))
    # along it: -rate * p_y plus a creep per direction of turn
    design = np.column_stack([-rate, (rate < 0).astype(float), (rate > 0).astype(float)])[turning]
    root_w = np.sqrt(w_f[turning])
    coef = np.linalg.lstsq(design * root_w[:, None], mean.real[turning] * root_w, rcond=None)[0]
    mean[turning] = design @ coef + 1j * rate[turning] * p_x
    mean[~turning] = mean[~turning].real
    mean[0] = 0.0  # standing
    return _Signatures(mean, np.maximum(sf, SPREAD_FLOOR_MPS), np.maximum(sl, SPREAD_FLOOR_MPS))


def _stop_bins(t_s: np.ndarray, xy: np.ndarray, a: int, b: int) -> tuple[np.ndarray, np.ndarray, float]:
    """The stop between motions ``a - 1`` and ``b`` cut into bins of about :data:`STOP_BIN_S`: their
    edges [s], the point's displacement in each (``x + 1j * y``, m) and their length [s]."""
    t0, t1 = t_s[a - 1], t_s[b]
    n = max(int(round((t1 - t0) / STOP_BIN_S)), 1)
    edges = np.linspace(t0, t1, n + 1)
    ex = np.interp(edges, t_s[a - 1 : b + 1], xy[a - 1 : b + 1, 0])
    ey = np.interp(edges, t_s[a - 1 : b + 1], xy[a - 1 : b + 1, 1])
    return edges, np.diff(ex + 1j * ey), float((t1 - t0) / n)


def _stops(t_s: np.ndarray, moving: np.ndarray) -> list[tuple[int, int]]:
    """``(a, b)``: the poses ``a .. b - 1`` stand still between two motions for at least
    :data:`MIN_STOP_S`."""
    edges = np.diff(np.concatenate([[0], (~moving).astype(np.int8), [0]]))
    out = []
    for a, b in zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()):
        if a > 0 and b < len(t_s) and t_s[b] - t_s[a - 1] >= MIN_STOP_S:
            out.append((a, b))
    return out


def decode_spot_turns(
    stamps_ns: np.ndarray, xy: np.ndarray, yaw_rad: np.ndarray, moving: np.ndarray
) -> tuple[np.ndarray, int]:
    """``yaw_rad`` (unwrapped, the ``smoothed`` method's: an even turn across each stop) with the
    stops whose point shows a signature decoded (see the module docstring); returns the new
    unwrapped yaw and the number of stops decoded."""
    t_s = (stamps_ns - stamps_ns[0]) / NS_PER_S
    xy = xy - xy[0]
    yaw = np.array(yaw_rad, dtype=np.float64)
    stops = [(a, b, *_stop_bins(t_s, xy, a, b)) for a, b in _stops(t_s, moving)]
    if not stops:
        return yaw, 0
    states = len(TURN_RATES_RAD_S)
    mean = np.zeros(states, dtype=complex)
    mean[-1] = _INITIAL_FORWARD_MPS
    sig = _Signatures(mean, _INITIAL_SPREAD_MPS.copy(), _INITIAL_SPREAD_MPS.copy())
    for round_ in range(EM_ITERATIONS + 1):
        stats = [_forward_backward(disp, dt_s, yaw[a - 1], yaw[b], sig) for a, b, _, disp, dt_s in stops]
        if round_ < EM_ITERATIONS:
            sig = _learn([(gamma, body, stop[4]) for (gamma, body, _), stop in zip(stats, stops)], sig)
    directionless = _Signatures(sig.mean_mps, sig.spread_forward_mps, sig.spread_left_mps, directionless=True)
    grid_unit = np.exp(1j * _grid())
    decoded = 0
    for (a, b, edges, disp, dt_s), (gamma, _, log_z) in zip(stops, stats):
        if not log_z - _forward_backward(disp, dt_s, yaw[a - 1], yaw[b], directionless)[2] > GATE_NATS:
            continue
        decoded += 1
        p = gamma.sum(axis=2)
        heading = np.angle(p @ grid_unit / p.sum(axis=1))
        h = np.unwrap(np.concatenate([[yaw[a - 1]], heading]))
        h += yaw[a - 1] - h[0]
        end = yaw[b] + 2 * np.pi * np.round((h[-1] - yaw[b]) / (2 * np.pi))  # the branch decoded
        shift = end - yaw[b]
        mids = (edges[:-1] + edges[1:]) / 2
        if shift == 0:  # the even turn the stop had
            even = np.interp(mids, t_s[a - 1 : b + 1], yaw[a - 1 : b + 1])
        else:  # another multiple of a full turn: even in time to that end
            even = yaw[a - 1] + (mids - t_s[a - 1]) / (t_s[b] - t_s[a - 1]) * (end - yaw[a - 1])
        blended = even + BLEND * (h[1:] - even)
        knots_t = np.concatenate([[t_s[a - 1]], mids, [t_s[b]]])
        knots = np.concatenate([[yaw[a - 1]], blended, [end]])
        yaw[a:b] = np.interp(t_s[a:b], knots_t, knots)
        yaw[b:] += shift
    return yaw, decoded
