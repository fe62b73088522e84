"""Open recordings in the Rerun viewer, natively or on the web, and render pictures without a display.

:func:`snapshot` runs the native viewer headless (it needs a Vulkan driver; on Debian the software
one, ``mesa-vulkan-drivers``, is enough), opens the file, moves the time cursor with Rerun's
``ViewerClient`` and saves a screenshot. :func:`view` and :func:`view_web_command` start the
``rerun`` executable that ships with the ``rerun-sdk`` package.
"""

from __future__ import annotations

import contextlib
import glob
import io
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from studio.core.errors import ConfigError, FormatError, OutputError, already_exists
from studio.core.types import PathLike
from studio.recording.colours import LIGHT_BACKGROUND_RGB
from studio.recording.entities import TIMELINE_CELL, TIMELINE_ITERATION, TIMELINE_NODE, TIMELINE_REPLAY_TICK
from studio.runtime.progress import Progress, report

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
    "WebViewer",
    "DEFAULT_WEB_PORT",
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


#: The web viewer's port when none is asked for and it is free (otherwise a free one is taken).
DEFAULT_WEB_PORT = 9090


@dataclass(frozen=True)
class WebViewer:
    """What ``studio view --web`` runs: the command and the two ports it serves on 127.0.0.1."""

    command: list[str]
    web_port: int
    """The web viewer's page (HTTP)."""
    grpc_port: int
    """The gRPC server the page reads the recording from."""

    @property
    def address(self) -> str:
        """The address to open in a browser: the web viewer, told where the recording is served."""
        return web_viewer_address(self.web_port, self.grpc_port)


def web_viewer_address(port: int, grpc_port: int) -> str:
    """The web viewer at ``port``, reading the recording from the gRPC server at ``grpc_port``."""
    return f"http://127.0.0.1:{port}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{grpc_port}%2Fproxy"


def _port_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def view_web_command(rrd: PathLike, *, port: int | None = None) -> WebViewer:
    """Serve ``rrd`` with the web viewer on 127.0.0.1 only. ``port`` is the page's port: a port
    asked for must be free (else one line naming it); without one, 9090 when free, else any free
    port. The gRPC server the page reads from always takes a free port, so several viewers can run
    at once."""
    if port is not None and not 0 < port < 65536:
        raise ConfigError(f"--port {port}: not a TCP port")
    path = _check_rrd(Path(rrd))
    if port is None:
        web = DEFAULT_WEB_PORT if _port_free(DEFAULT_WEB_PORT) else _free_port()
    elif _port_free(port):
        web = port
    else:
        raise ConfigError(f"--port {port}: 127.0.0.1:{port} is in use (leave --port out to take a free port)")
    grpc = _free_port()
    while grpc == web:
        grpc = _free_port()
    command = [
        rerun_executable(),
        "--serve-web",
        "--bind",
        "127.0.0.1",
        "--web-viewer-port",
        str(web),
        "--port",
        str(grpc),
        str(path),
    ]
    return WebViewer(command, web, grpc)


def run_viewer(command: list[str]) -> int:
    """Run a viewer command in the foreground; its exit code. The viewer ends with this process
    however it ends: on Ctrl+C (SIGINT), SIGTERM or SIGHUP it is stopped before this returns
    (``128 + signal`` for a signal), so no ``rerun`` is left serving under PID 1.

    A signal that arrives while the viewer is being started is held until ``Popen`` has returned
    (raised inside it, it would leave the new viewer running with nobody to stop it), and one that
    arrives while the viewer is being stopped does not interrupt the stopping."""
    import signal

    class _Stop(Exception):
        def __init__(self, signum: int) -> None:
            self.signum = signum

    started: list[subprocess.Popen[bytes]] = []
    pending: list[int] = []
    stopping = [False]

    def stop(signum: int, _frame: object) -> None:
        pending.append(signum)
        if started and not stopping[0]:
            raise _Stop(signum)

    previous = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    try:
        started.append(subprocess.Popen(command, env=_env(), start_new_session=True))
        if pending:
            raise _Stop(pending[0])
        return started[0].wait()
    except _Stop as why:
        return 128 + why.signum
    finally:
        stopping[0] = True
        if started and started[0].poll() is None:
            _stop_group(started[0])
        for s, handler in previous.items():
            signal.signal(s, handler)


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
    views_only: bool = False,
) -> SnapshotResult:
    """Render ``rrd`` to ``png`` with the cursor at ``node`` (default: the last node), no display needed.

    ``views_only`` hides the viewer's panels (top bar with its notifications, time panel, streams
    and selection panels) for the picture and trims the empty window strip above the views, so the
    picture holds only the recording's views: the form for a paper or the docs. The file is not
    changed.

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
        raise already_exists(png)
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
            views_only=views_only,
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


#: the viewer's panels, as its blueprint names them
_PANELS = ("/top_panel", "/blueprint_panel", "/selection_panel", "/time_panel")


def _hide_panels(client: Any) -> None:
    """Hide every panel around the views (the top panel carries the viewer's notifications)."""
    blueprint = client.get_blueprint().blueprint
    for path in _PANELS:
        kind = "TimePanelBlueprint" if path == "/time_panel" else "PanelBlueprint"
        blueprint.setdefault(path, {}).setdefault(kind, {})["state"] = "Hidden"
    client.set_blueprint(blueprint, of="recording")


def _steady_picture(client: Any, timeout_s: float) -> bytes:
    """A screenshot once two in a row are the same picture: the viewer's start-up notifications
    ("Headless viewer running…", the software rasterizer) fade out some 8-10 s after it starts and
    are drawn over the views whatever the panels."""
    import numpy as np
    from PIL import Image

    def pixels(png: bytes) -> Any:
        with Image.open(io.BytesIO(png)) as im:
            return np.asarray(im.convert("RGB"))

    deadline = time.monotonic() + timeout_s
    shot = client.take_screenshot()
    while time.monotonic() < deadline:
        time.sleep(1.0)
        again = client.take_screenshot()
        if np.array_equal(pixels(again), pixels(shot)):
            return bytes(again)
        shot = again
    return bytes(shot)


def _trim_top(png: Path) -> None:
    """Cut the empty strip above the views (the window's frame, left where the top panel was): down
    to its bottom edge, a full-width line of one light colour in the picture's top quarter."""
    import numpy as np
    from PIL import Image

    with Image.open(png) as im:
        rgb = np.asarray(im.convert("RGB"), dtype=np.float64)[: im.height // 4]
        edge = np.flatnonzero((rgb.mean(axis=(1, 2)) > 30.0) & (rgb.std(axis=(1, 2)) < 2.5))
        if edge.size:
            im.crop((0, int(edge[-1]) + 1, im.width, im.height)).save(png, format="PNG")


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
    views_only: bool = False,
) -> SnapshotResult:
    step = "snapshot"
    report(progress, step, 0, 4, "stages")
    with _headless_viewer(rrd, size, timeout_s, on_started=lambda: report(progress, step, 1, 4, "stages")) as (
        client,
        state,
    ):
        report(progress, step, 2, 4, "stages")
        rec = state.recordings[0]
        timelines = {t.name: t for t in rec.timelines}
        # a dataset's `node`, a solve's `iteration`, a sweep's `cell`, a replay's `tick`
        order = (TIMELINE_NODE, TIMELINE_ITERATION, TIMELINE_CELL, TIMELINE_REPLAY_TICK)
        name = next((t for t in order if t in timelines), None)
        if name is None:
            raise FormatError(f"{rrd}: no `node`, `iteration`, `cell` or `tick` timeline (not a studio recording?)")
        tl = timelines[name]
        at = tl.end if node is None else node
        if at is not None and tl.start is not None and not tl.start <= at <= tl.end:
            raise ConfigError(f"--node {node}: the recording's {name} timeline spans {tl.start}..{tl.end}")
        if theme == "light":
            _light_backgrounds(client)
        if views_only:
            _hide_panels(client)
        client.set_time(name, sequence=int(at), play_state="paused")
        time.sleep(settle_s)  # chunks stream in lazily after the cursor moves
        report(progress, step, 3, 4, "stages")
        if views_only:
            tmp.write_bytes(_steady_picture(client, timeout_s))
        else:
            client.save_screenshot(str(tmp.resolve()))
        report(progress, step, 4, 4, "stages")
        if not tmp.is_file():
            raise OutputError("the viewer did not write a screenshot")
        if views_only:
            _trim_top(tmp)
        return SnapshotResult(png, name, int(at))


@contextlib.contextmanager
def _headless_viewer(
    rrd: Path, size: str, timeout_s: float, on_started: Callable[[], None] | None = None
) -> Iterator[tuple[Any, Any]]:
    """A headless viewer with ``rrd`` loaded: ``(client, state right after loading)``; the viewer
    and every process it started are stopped on leaving."""
    from rerun.experimental import ViewerClient

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
        if on_started is not None:
            on_started()
        client.open(str(rrd))
        deadline = time.monotonic() + timeout_s
        while True:
            state = client.get_state()
            if state.recordings and not state.loading:
                break
            if time.monotonic() > deadline:
                raise OutputError(f"{rrd}: the viewer did not finish loading within {timeout_s:.0f} s")
            time.sleep(0.1)
        yield client, state
    finally:
        _stop_group(proc)
        log.close()


def opened_at(rrd: PathLike, *, timeout_s: float = 60.0) -> tuple[str | None, int | None]:
    """Where a viewer opening ``rrd`` puts its time cursor: ``(timeline, time)`` right after loading,
    nothing moved (studio recordings open at their end: their time panel is ``following``)."""
    rrd = _check_rrd(Path(rrd))
    with _headless_viewer(rrd, "800x500", timeout_s) as (_client, state):
        rec = state.recordings[0]
        return rec.current_timeline, rec.current_time


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
