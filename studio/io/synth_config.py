"""kollagen's JSON config: read, validate and write :class:`~generator.config.SynthConfig`.

Every problem is a :class:`~studio.core.errors.ConfigError` whose message names the file and the JSON path
(``agent_parameters.agent_specific[2].std_dev_angle``). Unknown keys are not errors (kollagen ignores
them) but are reported through ``warn`` with the closest known key.

Beyond kollagen's own rules, numbers whose arithmetic would overflow in the generator are refused:
a length, standard deviation or probability over :data:`~studio.core.units.MAX_MAGNITUDE` (1e9), a
stepsize or radius under :data:`~studio.core.units.MIN_MAGNITUDE` (1e-9 m), more than
:data:`MAX_AGENTS` agents, and JSON integers of more than 100 digits.
"""

from __future__ import annotations

import difflib
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, NoReturn

from studio.core.errors import ConfigError, FormatError
from studio.core.types import PathLike
from studio.core.units import MAX_MAGNITUDE, MIN_MAGNITUDE
from studio.generator.config import AgentConfig, InterLoopClosureConfig, SynthConfig
from studio.io.input_files import read_input_bytes
from studio.io.strict_json import unique_keys
from studio.io.studio_block import studio_block_to_json

__all__ = [
    "read_synth_config",
    "parse_synth_config",
    "synth_config_to_json",
    "MAX_CONFIG_BYTES",
    "MAX_AGENTS",
]

#: Larger files are refused before parsing (kollagen configs are a few kB).
MAX_CONFIG_BYTES = 16 * 1024 * 1024
#: Most agents a config may ask for (the paper's datasets have 5 and 8); a single ``agent_specific``
#: entry is repeated for each, so a huge count would exhaust memory while parsing.
MAX_AGENTS = 10_000

_TOP = (
    "number_of_steps",
    "align",
    "number_of_agents",
    "exact_information_matrix",
    "agent_parameters",
    "inter_agent_loop_closure_parameters",
    "studio",
)
_AGENT_PARAMS = ("stepsize", "step_fragment", "allow_retrocession", "agent_specific")
_AGENT = tuple(f.name for f in AgentConfig.__dataclass_fields__.values())
_INTER = tuple(f.name for f in InterLoopClosureConfig.__dataclass_fields__.values())
_SEEDS = {"random_number_generator_seed"}
_STD_DEVS = {
    "std_dev_position",
    "std_dev_angle",
    "std_dev_intra_loop_closure_position",
    "std_dev_intra_loop_closure_angle",
    "std_dev_loop_closure_position",
    "std_dev_loop_closure_angle",
}
_PROBABILITIES = {"same_position_intra_loop_closure_probability", "same_position_loop_closure_probability"}
_RADII = {"intra_loop_closure_radius", "loop_closure_radius"}
_INT32 = 2**31 - 1


class _Reader:
    def __init__(self, source: str, warn: Callable[[str], None] | None) -> None:
        self.source = source
        self.warn = warn

    def fail(self, path: str, msg: str) -> ConfigError:
        where = f"{self.source}: {path}" if path else self.source
        return ConfigError(f"{where}: {msg}")

    def obj(self, value: Any, path: str, known: tuple[str, ...]) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.fail(path, f"must be a JSON object, got {_kind(value)}")
        if self.warn is not None:
            for key in value:
                if key not in known:
                    close = difflib.get_close_matches(key, known, n=1)
                    hint = f" (did you mean {close[0]!r}?)" if close else ""
                    self.warn(f"{self.source}: {_join(path, key)}: unknown key, ignored{hint}")
        return value

    def get(self, obj: dict[str, Any], key: str, path: str) -> Any:
        if key not in obj:
            raise self.fail(_join(path, key), "missing key")
        return obj[key]

    def number(self, obj: dict[str, Any], key: str, path: str) -> float:
        v = self.get(obj, key, path)
        p = _join(path, key)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.fail(p, f"must be a number, got {_kind(v)}")
        try:
            v = float(v)
        except OverflowError:  # a JSON integer beyond the float range
            raise self.fail(p, "must be finite, got an integer beyond the float range") from None
        if not math.isfinite(v):
            raise self.fail(p, "must be finite")
        return v

    def integer(self, obj: dict[str, Any], key: str, path: str) -> int:
        v = self.get(obj, key, path)
        p = _join(path, key)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.fail(p, f"must be an integer, got {_kind(v)}")
        if isinstance(v, float):
            if not (math.isfinite(v) and v == int(v)):
                raise self.fail(p, f"must be an integer, got {v!r}")
            v = int(v)
        if not -_INT32 - 1 <= v <= _INT32:
            shown = str(v) if abs(v) < 10**30 else f"an integer of {len(str(abs(v)))} digits"
            raise self.fail(p, f"{shown} does not fit kollagen's 32-bit int")
        return v

    def boolean(self, obj: dict[str, Any], key: str, path: str) -> bool:
        v = self.get(obj, key, path)
        if not isinstance(v, bool):
            raise self.fail(_join(path, key), f"must be true or false, got {_kind(v)}")
        return v


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def _kind(v: Any) -> str:
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "a boolean"
    if isinstance(v, (int, float)):
        return f"the number {v!r}"
    if isinstance(v, str):
        return f"the string {v[:30]!r}"
    if isinstance(v, list):
        return "an array"
    return "an object"


def _section(r: _Reader, obj: dict[str, Any], path: str, names: tuple[str, ...]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name in names:
        p = _join(path, name)
        if name in _SEEDS:
            out[name] = r.integer(obj, name, path)
            continue
        v = r.number(obj, name, path)
        if name in _STD_DEVS and v < 0:
            raise r.fail(p, f"a standard deviation cannot be negative, got {v!r}")
        if name in _RADII and v <= 0:
            raise r.fail(p, f"must be positive, got {v!r}")
        if name in _RADII and v < MIN_MAGNITUDE:
            raise r.fail(p, f"{v!r} is under the smallest radius, {MIN_MAGNITUDE!r} m")
        if (
            name in _STD_DEVS or name in _RADII or name in _PROBABILITIES or name.endswith("probability_scaling")
        ) and v > MAX_MAGNITUDE:
            raise r.fail(p, f"{v!r} is over the largest value allowed, {MAX_MAGNITUDE!r}")
        if name.startswith("estimated_information") and v < 0:
            raise r.fail(p, f"information cannot be negative, got {v!r}")
        if (name in _PROBABILITIES or name.endswith("probability_scaling")) and v < 0:
            raise r.fail(p, f"cannot be negative, got {v!r}")
        out[name] = v
    return out


def parse_synth_config(
    data: Any, *, source: str = "<config>", name: str = "dataset", warn: Callable[[str], None] | None = None
) -> SynthConfig:
    """Validate a decoded JSON document and build the config."""
    r = _Reader(source, warn)
    top = r.obj(data, "", _TOP)
    n_agents = r.integer(top, "number_of_agents", "")
    if n_agents <= 0:
        raise r.fail("number_of_agents", f"must be at least 1, got {n_agents}")
    if n_agents > MAX_AGENTS:
        raise r.fail("number_of_agents", f"{n_agents} is over the limit of {MAX_AGENTS} agents")
    n_steps = r.integer(top, "number_of_steps", "")
    if n_steps <= 0:
        raise r.fail("number_of_steps", f"must be at least 1, got {n_steps}")
    align = r.boolean(top, "align", "")
    exact = r.boolean(top, "exact_information_matrix", "")
    ap = r.obj(r.get(top, "agent_parameters", ""), "agent_parameters", _AGENT_PARAMS)
    stepsize = r.number(ap, "stepsize", "agent_parameters")
    if stepsize <= 0:
        raise r.fail("agent_parameters.stepsize", f"must be positive, got {stepsize!r}")
    if not MIN_MAGNITUDE <= stepsize <= MAX_MAGNITUDE:
        raise r.fail("agent_parameters.stepsize", f"{stepsize!r} is outside [{MIN_MAGNITUDE!r}, {MAX_MAGNITUDE!r}] m")
    frag = r.integer(ap, "step_fragment", "agent_parameters")
    if frag <= 0:
        raise r.fail("agent_parameters.step_fragment", f"must be at least 1, got {frag}")
    retro = r.boolean(ap, "allow_retrocession", "agent_parameters")
    specs = r.get(ap, "agent_specific", "agent_parameters")
    if not isinstance(specs, list):
        raise r.fail("agent_parameters.agent_specific", f"must be an array, got {_kind(specs)}")
    if len(specs) not in (1, n_agents):
        raise r.fail(
            "agent_parameters.agent_specific",
            f"has {len(specs)} entries; it needs 1 (shared by all agents) or number_of_agents = {n_agents}",
        )
    agents = []
    for k, spec in enumerate(specs):
        path = f"agent_parameters.agent_specific[{k}]"
        agents.append(AgentConfig(**_section(r, r.obj(spec, path, _AGENT), path, _AGENT)))
    if len(agents) == 1:
        agents = agents * n_agents
    if exact:
        for k, a in enumerate(agents):
            for key in ("std_dev_position", "std_dev_angle"):
                if getattr(a, key) <= 0:
                    raise r.fail(
                        f"agent_parameters.agent_specific[{k}].{key}",
                        "must be positive when exact_information_matrix is true (the derived information "
                        "would be infinite)",
                    )
    ip = "inter_agent_loop_closure_parameters"
    inter = InterLoopClosureConfig(**_section(r, r.obj(r.get(top, ip, ""), ip, _INTER), ip, _INTER))
    studio = None
    if "studio" in top:
        from studio.io.studio_block import parse_studio_block

        studio = parse_studio_block(top["studio"], fail=r.fail, exact=exact)
    return SynthConfig(
        number_of_steps=n_steps,
        align=align,
        number_of_agents=n_agents,
        exact_information_matrix=exact,
        stepsize=stepsize,
        step_fragment=frag,
        allow_retrocession=retro,
        agents=tuple(agents),
        inter=inter,
        name=name,
        studio=studio,
    )


def read_synth_config(path: PathLike, *, warn: Callable[[str], None] | None = None) -> SynthConfig:
    """Read a kollagen JSON file; the dataset is named after the file's stem (as kollagen does), less a
    ``.config`` suffix, so the effective config ``OUT/<name>.config.json`` written by ``studio synth``
    makes ``<name>`` again."""
    path = Path(path)
    try:
        size = path.stat().st_size
        if path.is_dir():
            raise ConfigError(f"{path}: is a folder, not a JSON file")
        if size > MAX_CONFIG_BYTES:
            raise ConfigError(f"{path}: {size} bytes is too large for a config (limit {MAX_CONFIG_BYTES})")
        raw = read_input_bytes(path)  # a FIFO or device: refused, never waited on
    except FormatError as err:
        raise ConfigError(str(err)) from None
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such file") from None
    except OSError as err:
        raise ConfigError(f"{path}: cannot read ({err.strerror})") from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        line = raw[: err.start].count(b"\n") + 1
        raise ConfigError(f"{path}:{line}: not UTF-8 text") from None
    try:
        data = json.loads(text, parse_constant=_reject_constant, parse_int=_parse_int, object_pairs_hook=unique_keys)
    except json.JSONDecodeError as err:
        raise ConfigError(f"{path}:{err.lineno}:{err.colno}: invalid JSON: {err.msg}") from None
    except RecursionError:
        raise ConfigError(f"{path}: invalid JSON: nested too deeply") from None
    except ValueError as err:
        raise ConfigError(f"{path}{_constant_place(text, str(err))}: invalid JSON: {err}") from None
    name = path.stem
    if name.endswith(".config") and len(name) > len(".config"):
        name = name[: -len(".config")]
    if name in ("", ".", ".."):  # the outputs are named after it: ..json -> "."
        raise ConfigError(
            f"{path}: the dataset is named after the file's stem {name!r}, which names no folder; rename the file"
        )
    return parse_synth_config(data, source=str(path), name=name, warn=warn)


def _constant_place(text: str, message: str) -> str:
    """``:LINE:COLUMN`` of the first ``NaN``/``Infinity`` literal outside strings, when ``message``
    is about one (the decoder's hook is not told where it is), else ``""``."""
    if "is not valid JSON" not in message:
        return ""
    import re

    for m in re.finditer(r'"(?:[^"\\]|\\.)*"|-?Infinity|NaN', text):
        if not m.group().startswith('"'):
            line = text.count("\n", 0, m.start()) + 1
            return f":{line}:{m.start() - (text.rfind(chr(10), 0, m.start()) + 1) + 1}"
    return ""


def _reject_constant(name: str) -> NoReturn:
    raise ValueError(f"{name} is not valid JSON")


def _parse_int(text: str) -> int:
    if len(text) > 100:  # Python refuses over 4300 digits anyway, with a message about its own limit
        raise ValueError(f"an integer of {len(text.lstrip('-'))} digits is too long")
    return int(text)


def synth_config_to_json(cfg: SynthConfig) -> dict[str, Any]:
    """The config as kollagen's JSON document (one ``agent_specific`` entry per agent)."""

    def fields(obj: Any) -> dict[str, Any]:
        return {k: getattr(obj, k) for k in obj.__dataclass_fields__}

    return {
        "number_of_steps": cfg.number_of_steps,
        "align": cfg.align,
        "number_of_agents": cfg.number_of_agents,
        "exact_information_matrix": cfg.exact_information_matrix,
        "agent_parameters": {
            "stepsize": cfg.stepsize,
            "step_fragment": cfg.step_fragment,
            "allow_retrocession": cfg.allow_retrocession,
            "agent_specific": [fields(a) for a in cfg.agents],
        },
        "inter_agent_loop_closure_parameters": fields(cfg.inter),
        **({} if cfg.studio is None else {"studio": studio_block_to_json(cfg.studio)}),
    }
