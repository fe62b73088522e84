"""Open recordings in the Rerun viewer, natively or on the web, and render pictures without a display.

:func:`snapshot` runs the native viewer headless (it needs a Vulkan driver; on Debian the software
one, ``mesa-vulkan-drivers``, is enough), opens the file, moves the time cursor with Rerun's
``ViewerClient`` and saves a screenshot. :func:`view` and :func:`view_web_command` start the
``rerun`` executable that ships with the ``rerun-sdk`` package.
"""

from __future__ import annotations

import glob
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from studio.core.errors import ConfigError, FormatError, OutputError
from studio.core.progress import Progress, report
from studio.core.types import PathLike
from studio.recording.colours import LIGHT_BACKGROUND_RGB
from studio.recording.entities import TIMELINE_CELL, TIMELINE_ITERATION, TIMELINE_NODE

__all__ = [
    "SnapshotResult",
    "THEMES",
    "has_display",
    "rerun_executable",
    "vulkan_drivers",
    "snapshot",
    "view_command",
    "view_web_command",
    "web_viewer_address",
]

#: Where the Vulkan loader looks for installed drivers (ICD manifests).
_ICD_GLOBS = ("/usr/share/vulkan/icd.d/*.json", "/etc/vulkan/icd.d/*.json", "/usr/local/share/vulkan/icd.d/*.json")
_INSTALL_HINT = "install a Vulkan driver (Debian/Ubuntu: apt-get install -y mesa-vulkan-drivers)"


#: Themes :func:`snapshot` can render: the viewer's dark theme, or its views on the light theme's background.
THEMES = ("dark", "light")


@dataclass(frozen=True)
class SnapshotResult:
    path: Path
    timeline: str
    time: int | None
    """Where the cursor was (node index on the ``node`` timeline)."""


def rerun_executable() -> str:
    """The ``rerun`` executable of the installed rerun-sdk (beside this Python first, then PATH)."""
    beside = Path(sys.executable).parent / "rerun"
    if beside.is_file() and os.access(beside, os.X_OK):
        return str(beside)
    found = shutil.which("rerun")
    if found is None:
        raise ConfigError("the `rerun` executable was not found: install the rerun-sdk package")
    return found


def vulkan_drivers() -> list[str]:
    """Installed Vulkan driver manifests (empty: the headless viewer cannot render)."""
    extra = os.environ.get("VK_ICD_FILENAMES") or os.environ.get("VK_DRIVER_FILES")
    found = [p for p in (extra or "").split(os.pathsep) if p and os.path.isfile(p)]
    for pattern in _ICD_GLOBS:
        found += sorted(glob.glob(pattern))
    return found


def _check_rrd(rrd: Path) -> Path:
    """The recording's resolved path, once its header, footer and manifest read back (milliseconds,
    so a damaged file is refused before a viewer starts)."""
    from studio.io.atomic import verify_rrd

    if rrd.is_dir():
        raise FormatError(f"{rrd}: is a folder, not a recording")
    if not rrd.is_file():
        raise FormatError(f"{rrd}: no such recording")
    if rrd.suffix != ".rrd":
        raise FormatError(f"{rrd}: not a .rrd file")
    try:
        verify_rrd(rrd)
    except OutputError as err:
        raise FormatError(str(err).replace("the recording is incomplete", "not a complete Rerun recording")) from None
    return rrd.resolve()


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["RERUN_ANALYTICS"] = "0"
    env.setdefault("XDG_RUNTIME_DIR", "/tmp")
    return env


def has_display() -> bool:
    """False on Linux when neither ``DISPLAY`` nor ``WAYLAND_DISPLAY`` is set (no window can open)."""
    if not sys.platform.startswith("linux"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def view_command(rrd: PathLike) -> list[str]:
    """The command that opens ``rrd`` in the native viewer (refused without a display)."""
    path = _check_rrd(Path(rrd))
    if not has_display():
        raise ConfigError(
            f"{rrd}: no display (DISPLAY and WAYLAND_DISPLAY are unset): use "
            f"`studio view {rrd} --web` for the web viewer, or `studio snapshot {rrd} -o FILE.png`"
        )
    return [rerun_executable(), "--bind", "127.0.0.1", str(path)]


#: Port of the gRPC server that ``rerun --serve-web`` starts beside the web viewer (Rerun's default).
GRPC_PORT = 9876


def web_viewer_address(port: int) -> str:
    """The address to open in a browser: the web viewer, told where the recording is served."""
    return f"http://127.0.0.1:{port}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{GRPC_PORT}%2Fproxy"


def view_web_command(rrd: PathLike, *, port: int = 9090) -> list[str]:
    """The command that serves ``rrd`` with the web viewer on 127.0.0.1 only."""
    if not 0 < port < 65536:
        raise ConfigError(f"--port {port}: not a TCP port")
    return [
        rerun_executable(),
        "--serve-web",
        "--bind",
        "127.0.0.1",
        "--web-viewer-port",
        str(port),
        "--port",
        str(GRPC_PORT),
        str(_check_rrd(Path(rrd))),
    ]


def run_viewer(command: list[str]) -> int:
    """Run a viewer command in the foreground; its exit code."""
    return subprocess.call(command, env=_env())


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _parse_size(window_size: str) -> str:
    w, sep, h = window_size.lower().partition("x")
    if not (sep and w.isdigit() and h.isdigit() and 100 <= int(w) <= 8000 and 100 <= int(h) <= 8000):
        raise ConfigError(f"--size {window_size!r}: expected WIDTHxHEIGHT, e.g. 1400x900")
    return f"{int(w)}x{int(h)}"


def snapshot(
    rrd: PathLike,
    png: PathLike,
    *,
    node: int | None = None,
    window_size: str = "1400x900",
    timeout_s: float = 60.0,
    settle_s: float = 3.0,
    progress: Progress | None = None,
    force: bool = False,
    theme: str = "dark",
) -> SnapshotResult:
    """Render ``rrd`` to ``png`` with the cursor at ``node`` (default: the last node), no display needed.

    ``theme="light"`` gives every view the light theme's background (Rerun's ``viewport_background``
    token of the light theme, white), through the viewer's blueprint API; the viewer's own panels
    stay dark, because the headless viewer of Rerun 0.41 always runs the dark theme (it has no theme
    flag, setting or environment variable). The file is not changed.

    Raises :class:`ConfigError` with an installation hint when no Vulkan driver is installed. The
    picture is written atomically (a partial file is never left at ``png``). ``progress`` hears of
    the four stages: viewer started, recording loaded, cursor moved, picture saved.
    """

    rrd = _check_rrd(Path(rrd))
    png = Path(png)
    if png.suffix.lower() != ".png":
        raise OutputError(f"{png}: a snapshot must end in .png")
    if not png.parent.is_dir():
        raise OutputError(f"{png.parent}: no such folder")
    if png.is_dir():
        raise OutputError(f"{png}: is a folder")
    if (png.exists() or png.is_symlink()) and not force:
        raise OutputError(f"{png} already exists (use --force to overwrite)")
    size = _parse_size(window_size)
    if theme not in THEMES:
        raise ConfigError(f"--theme {theme!r}: expected one of {', '.join(THEMES)}")
    if not vulkan_drivers():
        raise ConfigError(f"studio snapshot needs a Vulkan driver and found none: {_INSTALL_HINT}")
    from studio.io.atomic import staged_outputs

    with staged_outputs(png.parent, [png.name], force=force, inputs=[rrd]) as staging:
        return _snapshot_into(
            rrd,
            png,
            staging / png.name,
            node=node,
            size=size,
            timeout_s=timeout_s,
            settle_s=settle_s,
            progress=progress,
            theme=theme,
        )


def _light_backgrounds(client: Any) -> None:
    """Put the light theme's background behind every spatial view and plot of the blueprint on screen."""
    colour = "#{:02x}{:02x}{:02x}".format(*LIGHT_BACKGROUND_RGB)
    blueprint = client.get_blueprint().blueprint
    for path, parts in list(blueprint.items()):
        kind = parts.get("ViewBlueprint", {}).get("class_identifier")
        if kind in ("3D", "2D"):
            blueprint[f"{path}/Background"] = {"Background": {"kind": "SolidColor", "color": colour}}
        elif kind == "TimeSeries":
            blueprint[f"{path}/PlotBackground"] = {"PlotBackground": {"color": colour}}
    client.set_blueprint(blueprint, of="recording")


def _snapshot_into(
    rrd: Path,
    png: Path,
    tmp: Path,
    *,
    node: int | None,
    size: str,
    timeout_s: float,
    settle_s: float,
    progress: Progress | None,
    theme: str = "dark",
) -> SnapshotResult:
    from rerun.experimental import ViewerClient

    step = "snapshot"
    report(progress, step, 0, 4, "stages")
    port = _free_port()
    cmd = [
        rerun_executable(),
        "--headless",
        "--hide-welcome-screen",
        "--bind",
        "127.0.0.1",
        "--port",
        str(port),
        "--window-size",
        size,
    ]
    log = tempfile.TemporaryFile(mode="w+", encoding="utf-8", errors="replace")  # never a full pipe
    # its own process group: the viewer starts helper processes that must end with it
    proc = subprocess.Popen(cmd, env=_env(), stdin=subprocess.DEVNULL, stdout=log, stderr=log, start_new_session=True)
    try:
        client = _connect(ViewerClient, proc, log, port, timeout_s)
        report(progress, step, 1, 4, "stages")
        client.open(str(rrd))
        deadline = time.monotonic() + timeout_s
        while True:
            state = client.get_state()
            if state.recordings and not state.loading:
                break
            if time.monotonic() > deadline:
                raise OutputError(f"{rrd}: the viewer did not finish loading within {timeout_s:.0f} s")
            time.sleep(0.1)
        report(progress, step, 2, 4, "stages")
        rec = state.recordings[0]
        timelines = {t.name: t for t in rec.timelines}
        # a dataset's `node`, a solve's `iteration`, a sweep's `cell`
        name = next((t for t in (TIMELINE_NODE, TIMELINE_ITERATION, TIMELINE_CELL) if t in timelines), None)
        if name is None:
            raise FormatError(f"{rrd}: no `node`, `iteration` or `cell` timeline (not a studio recording?)")
        tl = timelines[name]
        at = tl.end if node is None else node
        if at is not None and tl.start is not None and not tl.start <= at <= tl.end:
            raise ConfigError(f"--node {node}: the recording's {name} timeline spans {tl.start}..{tl.end}")
        if theme == "light":
            _light_backgrounds(client)
        client.set_time(name, sequence=int(at), play_state="paused")
        time.sleep(settle_s)  # chunks stream in lazily after the cursor moves
        report(progress, step, 3, 4, "stages")
        client.save_screenshot(str(tmp.resolve()))
        report(progress, step, 4, 4, "stages")
        if not tmp.is_file():
            raise OutputError("the viewer did not write a screenshot")
        return SnapshotResult(png, name, int(at))
    finally:
        _stop_group(proc)
        log.close()


def _stop_group(proc: subprocess.Popen[bytes]) -> None:
    """Stop the viewer and every process it started (SIGTERM, then SIGKILL after 10 s)."""
    import signal

    for sig, wait_s in ((signal.SIGTERM, 10.0), (signal.SIGKILL, None)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            break
        deadline = time.monotonic() + (wait_s or 10.0)
        while time.monotonic() < deadline:
            try:
                os.killpg(proc.pid, 0)
            except ProcessLookupError:
                proc.wait()
                return
            proc.poll()
            time.sleep(0.05)
    proc.wait()


def _connect(client_cls: Any, proc: subprocess.Popen[bytes], log: IO[str], port: int, timeout_s: float) -> Any:
    deadline = time.monotonic() + timeout_s
    url = f"rerun+http://127.0.0.1:{port}/proxy"
    last: Exception | None = None
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            log.seek(0)
            err = log.read().strip().splitlines()
            tail = next((ln for ln in reversed(err) if ln.strip()), "no output")
            if "adapter" in tail.lower() or "vulkan" in tail.lower():
                raise ConfigError(f"the headless viewer found no graphics adapter: {_INSTALL_HINT}")
            raise OutputError(f"the headless viewer exited with code {proc.returncode}: {tail[-300:]}")
        try:
            client = client_cls.connect(url)
            client.get_state()
            return client
        except Exception as err:  # the server is not up yet
            last = err
            time.sleep(0.2)
    raise OutputError(f"the headless viewer did not answer on port {port} within {timeout_s:.0f} s ({last})")
