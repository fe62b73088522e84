"""Communication models for a team of robots (pure numpy, deterministic, seeded; no I/O).

Time runs on a regular grid of *ticks* (``start_ns + i * step_ns``). A model says, at every tick,
which pairs of robots can talk (:func:`contacts`); :func:`deliver` then says when each inter-agent
loop closure reaches its two robots: at the first tick, at or after the closure becomes measurable,
at which its two robots are in contact and the link has room for it (a bandwidth limit per link
queues the rest, oldest first, for the next ticks of contact). Both robots of a closure learn it at
that tick (they are in contact); a closure whose robots never meet again is never delivered (-1).

The models are declared in :data:`studio.core.comms_registry.COMMS_MODELS` (name, grammar, help
and parser: ``studio replay --comms`` and its messages are built from it); their classes and parsers
are here. ``rendezvous:FILE`` reads Swarm-SLAM's simulated rendezvous, one line per robot
``ROBOT_ID,start,end,start,end,...`` (robot ids 0-based in the dataset's agent order, times in whole
seconds from the replay's start, windows inclusive; :mod:`studio.io.rendezvous_txt`). ``recorded``
takes the schedule from the dataset itself: a pair is in contact at the tick of each of its closures.

Positions between ground-truth stamps are interpolated linearly; a robot is present from its first
stamp and stays at its last position after its last one (it still talks).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from studio.core.errors import ConfigError
from studio.core.units import MAX_MAGNITUDE, NS_PER_S

__all__ = [
    "Always",
    "Never",
    "RangeLimited",
    "Rendezvous",
    "Recorded",
    "PartnerCap",
    "CommsModel",
    "Bandwidth",
    "Schedule",
    "CommsReport",
    "parse_comms",
    "parse_always",
    "parse_never",
    "parse_range",
    "parse_rendezvous",
    "parse_recorded",
    "parse_cap_options",
    "parse_bandwidth",
    "robot_pairs",
    "tick_grid",
    "contacts",
    "deliver",
    "comms_report",
    "check_windows",
]


@dataclass(frozen=True)
class Always:
    def spec(self) -> str:
        return "always"


@dataclass(frozen=True)
class Never:
    def spec(self) -> str:
        return "never"


@dataclass(frozen=True)
class RangeLimited:
    range_m: float
    """Robots within this distance [m] (ground truth, same time) can talk."""
    period_ns: int | None = None
    """Contacts only at the first tick of every period (None: at every tick)."""
    success_probability: float = 1.0
    """Each possible contact succeeds with this probability (drawn from the replay's seed)."""

    def spec(self) -> str:
        out = f"range:{self.range_m:g}"
        if self.period_ns is not None:
            out += f",period={self.period_ns / NS_PER_S:g}"
        if self.success_probability != 1.0:
            out += f",p={self.success_probability:g}"
        return out


@dataclass(frozen=True, eq=False)
class Rendezvous:
    windows_s: tuple[np.ndarray, ...]
    """Per robot, ``(k, 2)`` int64 ``[start, end]`` seconds from the replay's start, inclusive."""
    source: str = ""
    """Where the windows were read from (for the spec and messages)."""

    def spec(self) -> str:
        return f"rendezvous:{self.source}"


@dataclass(frozen=True)
class Recorded:
    """Each inter-robot closure delivered at the tick of its recorded time (when the dataset has it
    measured); its two robots are in contact at that tick only."""

    def spec(self) -> str:
        return "recorded"


@dataclass(frozen=True, eq=False)
class PartnerCap:
    """iMESA's communication model on top of a base model (``range`` or ``rendezvous``): at each
    tick the base says which pairs *could* talk; then, ``rounds`` times, the robots are put in a
    random order, each possible pair is taken in that order (i before j, then i before later j)
    while both robots have fewer than ``partners`` partners in this round, and each pair taken is
    kept with probability ``success_probability`` (a pair taken and lost still used its places, as
    in rpl-cmu/imesa-experiments' ``CommunicationModel::getStepCommunication``). The pairs kept in
    any round are in contact at the tick. One generator seeded by the replay's seed draws, tick by
    tick and round by round, the order and then one number per pair taken."""

    base: Any
    """The model saying who could talk (:class:`RangeLimited` without its own p, :class:`Rendezvous`,
    or, before the replay reads it, a rendezvous file's path)."""
    partners: int | None = None
    """Most partners per robot in one round (None: no cap)."""
    rounds: int = 1
    """Communication rounds per tick, each drawn afresh."""
    success_probability: float = 1.0

    def spec(self) -> str:
        out = f"rendezvous:{self.base}" if isinstance(self.base, str) else self.base.spec()
        if self.partners is not None:
            out += f",partners={self.partners}"
        if self.rounds != 1:
            out += f",rounds={self.rounds}"
        if self.success_probability != 1.0:
            out += f",p={self.success_probability:g}"
        return out

    def __eq__(self, other: object) -> bool:
        return isinstance(other, PartnerCap) and self.spec() == other.spec()

    def __hash__(self) -> int:
        return hash(self.spec())


CommsModel = Always | Never | RangeLimited | Rendezvous | Recorded | PartnerCap


@dataclass(frozen=True)
class Bandwidth:
    """At most ``rate_per_s`` closures (``unit="measurements"``) or bytes per second on each link."""

    rate_per_s: float
    unit: Literal["measurements", "bytes"] = "measurements"

    def spec(self) -> str:
        return f"{self.rate_per_s:g}{'/s' if self.unit == 'measurements' else 'B/s'}"


#: Most ticks a replay evaluates contacts on (each tick holds a bool per robot pair and, for a range
#: model, a position per robot): a million ticks of 8 robots are 28 MB of contacts and 192 MB of
#: positions; a kollagen dataset of 3,500 steps has 3,500 ticks at the default 1 s step.
MAX_TICKS = 1_000_000

_NUMBER = r"[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?"


def _positive(text: str, what: str, spec: str, *, allow_zero: bool = False) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ConfigError(f"comms: {what} in {spec!r} is not a number: {text!r}") from None
    if not np.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise ConfigError(f"comms: {what} in {spec!r} must be {'>= 0' if allow_zero else '> 0'}, got {text}")
    if value > MAX_MAGNITUDE:
        raise ConfigError(f"comms: {what} in {spec!r} must be at most {MAX_MAGNITUDE:g}, got {text}")
    return value


def parse_comms(spec: str) -> CommsModel | str:
    """A model from its text, by the parser its registry entry names
    (:data:`studio.core.comms_registry.COMMS_MODELS`); ``rendezvous:FILE`` gives back the FILE to read."""
    from studio.core.comms_registry import get_comms_model

    text = spec.strip()
    name, sep, arg = text.partition(":")
    parsed: CommsModel | str = get_comms_model(name, spec).parse(arg if sep else None, spec)
    return parsed


def _no_argument(name: str, arg: str | None, spec: str) -> None:
    if arg is not None:
        raise ConfigError(f"comms: {name} takes no argument, got {spec!r}")


def parse_always(arg: str | None, spec: str) -> Always:
    _no_argument("always", arg, spec)
    return Always()


def parse_never(arg: str | None, spec: str) -> Never:
    _no_argument("never", arg, spec)
    return Never()


def parse_recorded(arg: str | None, spec: str) -> Recorded:
    _no_argument("recorded", arg, spec)
    return Recorded()


#: The options of iMESA's model (:class:`PartnerCap`), taken by ``range`` and ``rendezvous``.
CAP_OPTIONS = ("partners", "rounds", "p")


def _count(text: str, what: str, spec: str) -> int:
    value = _positive(text, what, spec)
    if value != int(value):
        raise ConfigError(f"comms: {what} in {spec!r} must be a whole number, got {text}")
    return int(value)


def parse_cap_options(options: dict[str, str], spec: str) -> tuple[int | None, int, float]:
    """``partners``, ``rounds`` and ``p`` of ``options`` (key -> text): ``(partners or None,
    rounds, p)``; a bad value raises a ConfigError naming it and the spec."""
    partners = None if "partners" not in options else _count(options["partners"], "partners", spec)
    rounds = 1 if "rounds" not in options else _count(options["rounds"], "rounds", spec)
    p = 1.0
    if "p" in options:
        p = _positive(options["p"], "the success probability p", spec, allow_zero=True)
        if p > 1:
            raise ConfigError(f"comms: the success probability p in {spec!r} must be in [0, 1], got {options['p']}")
    return partners, rounds, p


def _options(parts: list[str], known: tuple[str, ...], spec: str) -> dict[str, str]:
    """``key=value`` parts as a dict; an unknown or repeated key raises, naming the known ones."""
    out: dict[str, str] = {}
    for part in parts:
        key, _, value = part.partition("=")
        key = key.strip()
        if key not in known:
            raise ConfigError(f"comms: unknown option {key!r} in {spec!r} (known: {', '.join(known)})")
        if key in out:
            raise ConfigError(f"comms: option {key!r} given twice in {spec!r}")
        out[key] = value
    return out


def parse_rendezvous(arg: str | None, spec: str) -> str | PartnerCap:
    """The FILE of ``rendezvous:FILE`` (read by the replay, which knows the number of robots); with
    iMESA's options after it (``,partners=K,rounds=N,p=P``, taken from the end), a :class:`PartnerCap`
    around that FILE."""
    parts = (arg or "").split(",")
    tail: list[str] = []
    while len(parts) > 1 and parts[-1].partition("=")[0].strip() in CAP_OPTIONS and "=" in parts[-1]:
        tail.insert(0, parts.pop())
    path = ",".join(parts)
    if not path:
        raise ConfigError("comms: rendezvous needs a file: rendezvous:FILE")
    if not tail:
        return path
    partners, rounds, p = parse_cap_options(_options(tail, CAP_OPTIONS, spec), spec)
    return PartnerCap(path, partners, rounds, p)


def parse_range(arg: str | None, spec: str) -> RangeLimited | PartnerCap:
    """``range:R[,period=T][,p=P][,partners=K][,rounds=N]``: with partners or rounds, iMESA's model
    (:class:`PartnerCap`, p drawn after the cap) around the range."""
    if arg is None:
        raise ConfigError(f"comms: range needs a distance in metres: range:R, got {spec!r}")
    parts = arg.split(",")
    range_m = _positive(parts[0], "the range [m]", spec)
    options = _options(parts[1:], ("period",) + CAP_OPTIONS, spec)
    period_ns: int | None = None
    if "period" in options:
        period_ns = round(_positive(options["period"], "period [s]", spec) * NS_PER_S)
        if period_ns <= 0:
            raise ConfigError(
                f"comms: period in {spec!r} is below the replay's 1 ns clock (at least 1e-9 s), got {options['period']}"
            )
    partners, rounds, p = parse_cap_options(options, spec)
    if partners is None and rounds == 1:
        return RangeLimited(range_m, period_ns, p)
    return PartnerCap(RangeLimited(range_m, period_ns), partners, rounds, p)


def parse_bandwidth(spec: str) -> Bandwidth:
    """``N/s`` (closures per second per link) or ``NB/s`` (bytes per second per link)."""
    m = re.fullmatch(rf"\s*({_NUMBER})\s*(B?)/s\s*", spec)
    if m is None:
        raise ConfigError(f"bandwidth: expected N/s (measurements) or NB/s (bytes) per link, got {spec!r}")
    rate = float(m.group(1))
    if not 0 < rate <= MAX_MAGNITUDE:
        raise ConfigError(f"bandwidth: must be > 0 and at most {MAX_MAGNITUDE:g}, got {spec!r}")
    return Bandwidth(rate, "bytes" if m.group(2) else "measurements")


def check_windows(windows_s: tuple[np.ndarray, ...], where: list[str]) -> None:
    """Raise a ConfigError naming ``where[k]`` (e.g. ``file:line``) for a robot whose windows have
    negative times, end before they start, or are out of order or overlapping."""
    for k, w in enumerate(windows_s):
        for j in range(len(w)):
            start, end = int(w[j, 0]), int(w[j, 1])
            if start < 0 or end < 0:
                raise ConfigError(f"{where[k]}: window {j + 1} has a negative time ({start}, {end})")
            if end < start:
                raise ConfigError(f"{where[k]}: window {j + 1} ends ({end}) before it starts ({start})")
            if j and start <= int(w[j - 1, 1]):
                raise ConfigError(
                    f"{where[k]}: window {j + 1} ({start}, {end}) is out of order or overlaps window {j} "
                    f"({int(w[j - 1, 0])}, {int(w[j - 1, 1])})"
                )


def robot_pairs(num_robots: int) -> np.ndarray:
    """``(P, 2)`` pairs ``i < j``, lexicographic: the column order of every per-link array."""
    i, j = np.triu_indices(num_robots, k=1)
    return np.column_stack([i, j]).astype(np.int64).reshape(-1, 2)


def tick_grid(start_ns: int, end_ns: int, step_ns: int) -> np.ndarray:
    if step_ns <= 0:
        raise ConfigError(f"step: must be a positive duration, got {step_ns} ns")
    count = (end_ns - start_ns) // step_ns + 1
    if count > MAX_TICKS:
        raise ConfigError(
            f"step: {step_ns / NS_PER_S:g} s makes {count:,} ticks over {(end_ns - start_ns) / NS_PER_S:g} s, "
            f"over the limit of {MAX_TICKS:,}; use a larger step",
            option="step",
        )
    return np.asarray(start_ns + np.arange(count, dtype=np.int64) * np.int64(step_ns))


def _positions_at(stamps_ns: np.ndarray, positions_xyz: np.ndarray, ticks_ns: np.ndarray) -> np.ndarray:
    t = (stamps_ns - stamps_ns[0]).astype(np.float64)
    q = (ticks_ns - stamps_ns[0]).astype(np.float64)
    return np.column_stack([np.interp(q, t, positions_xyz[:, c]) for c in range(positions_xyz.shape[1])])


def _recorded_contacts(
    ticks_ns: np.ndarray, num_pairs: int, closure_pair: np.ndarray, measured_ns: np.ndarray
) -> np.ndarray:
    """``recorded``: each pair in contact at the first tick at or after each of its closures' times
    (a closure after the last tick is never delivered, as under ``always``)."""
    out = np.zeros((len(ticks_ns), num_pairs), dtype=bool)
    tick = np.searchsorted(ticks_ns, measured_ns, side="left")
    keep = (closure_pair >= 0) & (tick < len(ticks_ns))
    out[tick[keep], closure_pair[keep]] = True
    return out


def _capped(possible: np.ndarray, n: int, model: PartnerCap, seed: int) -> np.ndarray:
    """iMESA's choice of partners (:class:`PartnerCap`) among the ``possible`` pairs of each tick."""
    out = np.zeros_like(possible)
    if n < 2:
        return out
    column = np.full((n, n), -1, dtype=np.int64)
    pairs = robot_pairs(n)
    column[pairs[:, 0], pairs[:, 1]] = column[pairs[:, 1], pairs[:, 0]] = np.arange(len(pairs))
    cap = n if model.partners is None else model.partners
    rng = np.random.default_rng(seed)
    for t in np.flatnonzero(possible.any(axis=1)).tolist():
        row = possible[t]
        for _ in range(model.rounds):
            order = rng.permutation(n).tolist()
            load = [0] * n
            taken = []
            for i, a in enumerate(order):
                for b in order[i + 1 :]:
                    p = int(column[a, b])
                    if load[a] < cap and load[b] < cap and row[p]:
                        taken.append(p)
                        load[a] += 1
                        load[b] += 1
            kept = rng.random(len(taken)) < model.success_probability
            out[t, np.asarray(taken, dtype=np.int64)[kept]] = True
    return out


def contacts(
    model: CommsModel,
    *,
    ticks_ns: np.ndarray,
    pose_ns: tuple[np.ndarray, ...],
    positions_xyz: tuple[np.ndarray, ...] | None,
    seed: int = 0,
    closure_pair: np.ndarray | None = None,
    measured_ns: np.ndarray | None = None,
) -> np.ndarray:
    """``(ticks, P)`` bool: which pairs (:func:`robot_pairs` order) can talk at each tick.

    ``positions_xyz`` (per robot, ground truth at ``pose_ns``) is needed by ``range``; the
    inter-agent closures (``closure_pair`` as :func:`deliver` takes it, ``measured_ns``) by
    ``recorded``."""
    n = len(pose_ns)
    pairs = robot_pairs(n)
    m = len(ticks_ns)
    present = np.column_stack([ticks_ns >= s[0] for s in pose_ns]) if n else np.zeros((m, 0), bool)
    both = present[:, pairs[:, 0]] & present[:, pairs[:, 1]]
    if isinstance(model, Always):
        return np.asarray(both)
    if isinstance(model, Never):
        return np.zeros_like(both)
    if isinstance(model, RangeLimited):
        if positions_xyz is None:
            raise ConfigError("comms: range needs every robot's ground truth (this dataset has none)")
        where = np.stack([_positions_at(s, p, ticks_ns) for s, p in zip(pose_ns, positions_xyz)], axis=1)
        d = np.linalg.norm(where[:, pairs[:, 0]] - where[:, pairs[:, 1]], axis=2)
        ok = both & (d <= model.range_m)
        if model.period_ns is not None:
            phase = (ticks_ns - ticks_ns[0]) // model.period_ns
            first = np.concatenate([[True], phase[1:] != phase[:-1]])
            ok &= first[:, None]
        if model.success_probability < 1.0:
            draws = np.random.default_rng(seed).random(ok.shape)
            ok &= draws < model.success_probability
        return np.asarray(ok)
    if isinstance(model, PartnerCap):
        if isinstance(model.base, str):
            raise ConfigError(f"comms: {model.base}: the rendezvous file must be read first")
        possible = contacts(
            model.base,
            ticks_ns=ticks_ns,
            pose_ns=pose_ns,
            positions_xyz=positions_xyz,
            seed=seed,
            closure_pair=closure_pair,
            measured_ns=measured_ns,
        )
        return _capped(possible, n, model, seed)
    if isinstance(model, Recorded):
        if closure_pair is None or measured_ns is None:
            raise ConfigError("comms: recorded needs the dataset's inter-agent closures")
        return _recorded_contacts(ticks_ns, len(pairs), closure_pair, measured_ns)
    if isinstance(model, Rendezvous):
        if len(model.windows_s) != n:
            raise ConfigError(f"comms: {model.source} has windows for {len(model.windows_s)} robots, dataset {n}")
        rel_s = (ticks_ns - ticks_ns[0]) / NS_PER_S
        alive = np.zeros((m, n), dtype=bool)
        for k, w in enumerate(model.windows_s):
            for start, end in w.tolist():
                alive[:, k] |= (rel_s >= start) & (rel_s <= end)
        return np.asarray(both & alive[:, pairs[:, 0]] & alive[:, pairs[:, 1]])
    raise ConfigError(f"comms: unknown model {model!r}")


def deliver(
    contact: np.ndarray,
    *,
    ticks_ns: np.ndarray,
    closure_pair: np.ndarray,
    measured_ns: np.ndarray,
    bandwidth: Bandwidth | None = None,
    closure_bytes: int = 0,
    step_ns: int = NS_PER_S,
) -> np.ndarray:
    """Per closure, the index of the tick at which both its robots learn it, or -1 (module doc).

    ``closure_pair`` is each closure's column in ``contact`` (-1: both ends on one robot, known at
    once). With a bandwidth, each link carries ``rate x step`` closures (or bytes) per tick of
    contact, fractions carried over while the link stays up; the oldest waiting go first."""
    n = len(measured_ns)
    first_tick = np.searchsorted(ticks_ns, measured_ns, side="left")
    out = np.full(n, -1, dtype=np.int64)
    own = closure_pair < 0
    out[own] = np.minimum(first_tick[own], len(ticks_ns) - 1)
    if bandwidth is not None:
        per_tick = bandwidth.rate_per_s * step_ns / NS_PER_S
        if bandwidth.unit == "bytes":
            per_tick /= max(closure_bytes, 1)
    for p in np.unique(closure_pair[~own]).tolist():
        members = np.flatnonzero(closure_pair == p)
        members = members[np.argsort(first_tick[members], kind="stable")]
        up = np.flatnonzero(contact[:, p])
        if bandwidth is None:
            j = np.searchsorted(up, first_tick[members], side="left")
            hit = j < len(up)
            out[members[hit]] = up[j[hit]]
            continue
        ready = first_tick[members]
        nxt = 0
        credit = 0.0
        previous = -2
        for t in up.tolist():
            if nxt >= len(members):
                break
            if t != previous + 1:
                credit = 0.0  # the link dropped: what was left of its capacity is lost
            previous = t
            credit += per_tick
            waiting = int(np.searchsorted(ready, t, side="right")) - nxt
            take = min(int(credit + 1e-9), waiting)
            if take > 0:
                out[members[nxt : nxt + take]] = t
                nxt += take
                credit -= take
            if waiting == take:
                credit = min(credit, per_tick)
    return out


@dataclass(frozen=True, eq=False)
class Schedule:
    """When robots can talk and when each inter-agent closure reaches its robots."""

    model: str
    """The model's spec (``range:5,period=2``...)."""
    robots: tuple[str, ...]
    ticks_ns: np.ndarray
    contact: np.ndarray
    """``(ticks, P)`` bool, pairs in :func:`robot_pairs` order."""
    closure_from: np.ndarray
    """Per inter-agent closure, its two robots (0-based)."""
    closure_to: np.ndarray
    measured_ns: np.ndarray
    delivered_tick: np.ndarray
    """Per closure, the tick at which both robots learn it, -1 for never."""
    seed: int = 0
    bandwidth: str = ""
    extras: dict[str, Any] = field(default_factory=dict)

    @property
    def pairs(self) -> np.ndarray:
        return robot_pairs(len(self.robots))

    @property
    def delivered_ns(self) -> np.ndarray:
        """Per closure, when both robots learn it, -1 for never."""
        return np.where(self.delivered_tick >= 0, self.ticks_ns[np.maximum(self.delivered_tick, 0)], -1)

    def windows(self) -> np.ndarray:
        """``(W, 4)`` int64 rows ``robot_a, robot_b, first_tick, last_tick`` of every contact window
        (a maximal run of ticks in contact), by pair then time."""
        rows = []
        pairs = self.pairs
        for p in range(len(pairs)):
            up = self.contact[:, p].astype(np.int8)
            edges = np.diff(np.concatenate([[0], up, [0]]))
            starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
            for s, e in zip(starts.tolist(), ends.tolist()):
                rows.append((int(pairs[p, 0]), int(pairs[p, 1]), s, e))
        return np.asarray(rows, dtype=np.int64).reshape(-1, 4)


@dataclass(frozen=True, eq=False)
class CommsReport:
    """What a schedule means for the team (``report.md`` of a replay)."""

    robots: tuple[str, ...]
    contacts_per_pair: np.ndarray
    """``(P,)`` number of contact windows of each pair."""
    disconnections: np.ndarray
    """Per robot: how often it went from at least one neighbour to none."""
    connected_fraction: np.ndarray
    """Per robot: the fraction of ticks with at least one neighbour."""
    robots_in_contact: np.ndarray
    """Per tick: how many robots have at least one neighbour."""
    detected: np.ndarray
    """Per tick: inter-agent closures measurable by then (cumulative)."""
    delivered: np.ndarray
    """Per tick: inter-agent closures delivered by then (cumulative)."""


def neighbours_per_robot(schedule: Schedule) -> np.ndarray:
    """``(ticks, robots)`` int: how many robots each one is in contact with at each tick."""
    n = len(schedule.robots)
    pairs = schedule.pairs
    out = np.zeros((len(schedule.ticks_ns), n), dtype=np.int64)
    c = schedule.contact.astype(np.int64)
    for k in range(n):
        cols = np.flatnonzero((pairs[:, 0] == k) | (pairs[:, 1] == k))
        out[:, k] = c[:, cols].sum(axis=1)
    return out


def comms_report(schedule: Schedule) -> CommsReport:
    m = len(schedule.ticks_ns)
    windows = schedule.windows()
    pairs = schedule.pairs
    per_pair = np.zeros(len(pairs), dtype=np.int64)
    if len(windows):
        index = {(int(a), int(b)): k for k, (a, b) in enumerate(pairs.tolist())}
        for a, b in windows[:, :2].tolist():
            per_pair[index[(a, b)]] += 1
    linked = neighbours_per_robot(schedule) > 0
    drops = (linked[:-1] & ~linked[1:]).sum(axis=0) if m > 1 else np.zeros(len(schedule.robots), dtype=np.int64)
    first = np.searchsorted(schedule.ticks_ns, schedule.measured_ns, side="left")
    detected = np.cumsum(np.bincount(np.minimum(first, m - 1), minlength=m)) if m else np.zeros(0, np.int64)
    got = schedule.delivered_tick[schedule.delivered_tick >= 0]
    delivered = np.cumsum(np.bincount(got, minlength=m)) if m else np.zeros(0, np.int64)
    return CommsReport(
        schedule.robots,
        per_pair,
        drops.astype(np.int64),
        linked.mean(axis=0) if m else np.zeros(len(schedule.robots)),
        linked.sum(axis=1).astype(np.int64),
        detected.astype(np.int64),
        delivered.astype(np.int64),
    )
