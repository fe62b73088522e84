"""`studio convert`'s options per source: each source takes what its registry entry says and
refuses every other option (exit 2, one line naming the option and the source, nothing written),
and an option that needs another (a partition needs a split) is refused without it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.convert_config import ConvertOption, accepted_options, check_source_options, convert_options
from studio.converters.options import OPTION_NEEDS, GraphImportOptions
from studio.converters.registry import SOURCES
from studio.core.errors import ConfigError

OPTIONS = {o.name: o for o in convert_options()}


def _args(option: ConvertOption) -> list[str]:
    """The option on the command line with a valid value other than its default."""
    flag = "--" + option.flag.replace("_", "-")
    if isinstance(option.default, bool):
        return [flag]
    if isinstance(option.default, tuple):
        return [flag, "a=/x" if option.name == "agents" else "a=ufl"]
    if option.choices:
        return [flag, option.choices[-1]]
    return [flag, "2" if isinstance(option.default, int) else "0.5"]


def _refused(tmp_path: Path, source: str, args: list[str]) -> str:
    """Run `studio convert SOURCE IN -o OUT ARGS`: exit 2, one line, nothing written; the line."""
    given = tmp_path / "in.txt"
    given.write_text("")
    before = sorted(tmp_path.rglob("*"))
    res = CliRunner().invoke(app, ["convert", source, str(given), "-o", str(tmp_path / "out"), *args])
    assert res.exit_code == 2, res.output
    assert len(res.output.strip().splitlines()) == 1, res.output
    assert sorted(tmp_path.rglob("*")) == before
    return res.output.strip()


REFUSED = [
    (source, name) for source in SOURCES for name in OPTIONS if name not in accepted_options(source, synthesize=False)
]


@pytest.mark.parametrize(("source", "name"), REFUSED, ids=[f"{s}-{n}" for s, n in REFUSED])
def test_a_source_refuses_an_option_it_would_ignore(tmp_path, source, name):
    option = OPTIONS[name]
    line = _refused(tmp_path, source, _args(option))
    flag = "--" + option.flag.replace("_", "-")
    assert line.startswith(f"error: {flag}: studio convert {source} does not take it ("), line


def test_graph_sources_refuse_what_the_issue_found_ignored():
    """The options `studio convert g2o|jrl|dpgo|symbols` ignored silently (the old hand-written list
    named `body_frame`, the parameter is `body_frames`)."""
    ignored = (
        "heading_method",
        "odometry",
        "odometry_from",
        "sightings_as_closures",
        "keyframes_at_sightings",
        "body_frames",
    )
    graph = [name for name, src in SOURCES.items() if src.read_graph is not None]
    assert {"g2o", "jrl", "dpgo", "symbols"} <= set(graph)
    assert all((s, n) in REFUSED for s in graph for n in ignored)
    # and every source refuses something, so none takes every option unasked
    assert {s for s, _ in REFUSED} == set(SOURCES)


NEEDS = [
    (source, name) for source in SOURCES for name in OPTION_NEEDS if name in accepted_options(source, synthesize=False)
]


@pytest.mark.parametrize(("source", "name"), NEEDS, ids=[f"{s}-{n}" for s, n in NEEDS])
def test_an_option_without_the_one_it_needs_is_refused(tmp_path, source, name):
    option, needed = OPTIONS[name], OPTIONS[OPTION_NEEDS[name]]
    args = _args(option) if option.choices else ["--" + option.flag.replace("_", "-"), "1.5"]
    line = _refused(tmp_path, source, args)
    flag, needed_flag = ("--" + o.flag.replace("_", "-") for o in (option, needed))
    assert line == f"error: {flag}: studio convert {source} takes it only with {needed_flag}"
    # with the option it needs, the check lets it through
    check_source_options(source, {name: args[-1], needed.name: 2}, synthesize=SOURCES[source].read_graph is None)


def test_the_needs_hold_for_the_default_value_too_and_a_config_may_supply_the_split(tmp_path):
    """`--partition contiguous` (the default) without --split is refused as well: it was typed;
    a config that splits lets `--overlap` through."""
    line = _refused(tmp_path, "g2o", ["--partition", "contiguous"])
    assert line == "error: --partition: studio convert g2o takes it only with --split"
    check_source_options("tum", {"overlap_s": 2.0}, synthesize=True, base={"split": 3})
    with pytest.raises(ConfigError, match=r"^overlap_s: studio convert tum takes it only with split$"):
        check_source_options("tum", {"overlap_s": 2.0}, synthesize=True, base={"split": 0})


def test_the_library_refuses_a_partition_without_a_split():
    with pytest.raises(ConfigError, match="^partition: metis needs a split into robots") as err:
        GraphImportOptions(partition="metis")
    assert err.value.option == "partition"
    assert GraphImportOptions(split=2, partition="metis").partition == "metis"


def test_what_each_source_takes_is_built_from_its_entry():
    every: dict[str, Any] = {name: accepted_options(name, synthesize=False) for name in SOURCES}
    for name, src in SOURCES.items():
        taken = every[name]
        if src.read_graph is not None:
            assert taken == set(src.graph_options)
            continue
        assert ("agents" in taken) == src.takes_agents
        assert ("sightings_as_closures" in taken) == ("keyframes_at_sightings" in taken) == (src.sightings is not None)
        assert {"partition", "ground_truth"}.isdisjoint(taken) and {"split", "overlap_s", "seed"} <= taken
    # a graph source read through a config is synthesized like a trajectory source
    assert "seed" in accepted_options("jrl", synthesize=True)


def test_the_library_refuses_what_a_graph_source_would_ignore(tmp_path):
    """import_graph checks its options against the source's entry too: a JRL file has no `_GT.tum`
    beside it to choose from, so a ground-truth choice would be ignored."""
    from studio.graph_import import import_graph

    with pytest.raises(ConfigError, match=r"^ground_truth: studio convert jrl does not take it") as err:
        import_graph("jrl", [tmp_path / "x.jrl"], tmp_path / "out", options=GraphImportOptions(ground_truth="none"))
    assert err.value.option == "ground_truth" and not (tmp_path / "out").exists()
