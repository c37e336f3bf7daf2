"""Open a ropeload HTML report in headless Chromium and save a full-page PNG.

    uv run python scripts/screenshot_report.py ropeload-data/reports/<report>.html \\
        [-o report.png] [--width 1400]

Chromium (``chromium`` on PATH; Debian: ``apt-get install chromium``) is driven over the
DevTools protocol on a pipe (``--remote-debugging-pipe``: no port, no extra package):
it loads the file with every host name unresolvable (``--host-resolver-rules``), so a
report that needed the network would show empty plots; waits until every plotly figure
has drawn its SVG; measures the page and captures all of it. It prints the number of
figures drawn, the page size, and any request that was not to a ``file:`` or ``data:``
URL (a self-contained report makes none).

Also a module: :func:`render` returns a :class:`Rendering` (PNG bytes, figures found and
drawn, requests, page size) for tests.
"""

from __future__ import annotations

import argparse
import base64
import contextlib
import json
import os
import select
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["Rendering", "find_chromium", "render"]

_FLAGS = [
    "--headless",
    "--no-sandbox",  # as root in a container; the page is our own file
    "--disable-gpu",
    "--hide-scrollbars",
    "--no-first-run",
    "--no-default-browser-check",
    "--disable-extensions",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--mute-audio",
    "--host-resolver-rules=MAP * ~NOTFOUND",  # no network: a CDN script would fail
    "--remote-debugging-pipe",
]

#: JavaScript: how many plotly figures the page has, and how many have drawn (an SVG with
#: at least one trace path or bar).
_PROGRESS = """JSON.stringify({
  figures: document.querySelectorAll('div.plotly-graph-div').length,
  drawn: Array.from(document.querySelectorAll('div.plotly-graph-div')).filter(
    d => d.querySelector('svg.main-svg') !== null).length,
  with_data: Array.from(document.querySelectorAll('div.plotly-graph-div')).filter(
    d => d.querySelector('g.trace path, g.trace rect, g.points path') !== null).length,
  height: Math.ceil(document.documentElement.scrollHeight),
  plotly: typeof Plotly !== 'undefined'
})"""


def find_chromium() -> str | None:
    """The Chromium (or Chrome) executable on PATH, or None."""
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        found = shutil.which(name)
        if found:
            return found
    return None


@dataclass
class Rendering:
    """What the browser made of a report."""

    png: bytes
    width: int
    height: int
    figures: int
    drawn: int
    with_data: int
    plotly_loaded: bool
    requests: list[str] = field(default_factory=list)

    @property
    def external_requests(self) -> list[str]:
        return [u for u in self.requests if not u.startswith(("file:", "data:", "about:"))]


class _Pipe:
    """The DevTools protocol over Chromium's fds 3 (commands) and 4 (replies, events)."""

    def __init__(self, write_fd: int, read_fd: int, timeout_s: float) -> None:
        self.write_fd, self.read_fd = write_fd, read_fd
        self.deadline = time.monotonic() + timeout_s
        self.buffer = b""
        self.events: list[dict] = []
        self.next_id = 0

    def _message(self) -> dict:
        while b"\0" not in self.buffer:
            left = self.deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError("Chromium did not answer in time")
            ready, _, _ = select.select([self.read_fd], [], [], left)
            if not ready:
                continue
            chunk = os.read(self.read_fd, 1 << 20)
            if not chunk:
                raise ConnectionError("Chromium closed the DevTools pipe")
            self.buffer += chunk
        raw, self.buffer = self.buffer.split(b"\0", 1)
        return json.loads(raw)

    def call(self, method: str, session: str | None = None, **params: object) -> dict:
        self.next_id += 1
        message: dict[str, object] = {"id": self.next_id, "method": method, "params": params}
        if session:
            message["sessionId"] = session
        os.write(self.write_fd, json.dumps(message).encode() + b"\0")
        while True:
            reply = self._message()
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            self.events.append(reply)

    def wait_event(self, method: str, timeout_s: float) -> None:
        end = time.monotonic() + timeout_s
        while not any(e.get("method") == method for e in self.events):
            if time.monotonic() > end:
                return
            self.events.append(self._message())

    def evaluate(self, session: str, expression: str) -> object:
        result = self.call("Runtime.evaluate", session, expression=expression, returnByValue=True)
        return result.get("result", {}).get("value")


def render(
    report: str | Path, *, width: int = 1400, timeout_s: float = 120.0, settle_s: float = 1.0
) -> Rendering:
    """Load ``report`` in headless Chromium; wait for its figures; capture the full page.

    Raises FileNotFoundError without a Chromium on PATH, TimeoutError when the page
    does not finish drawing within ``timeout_s``.
    """
    browser = find_chromium()
    if browser is None:
        raise FileNotFoundError("no chromium on PATH (Debian: apt-get install chromium)")
    url = Path(report).resolve().as_uri()
    to_browser_r, to_browser_w = os.pipe()
    from_browser_r, from_browser_w = os.pipe()

    def wire_fds() -> None:  # in the child: its fd 3 reads our commands, fd 4 answers
        os.dup2(to_browser_r, 3)
        os.dup2(from_browser_w, 4)

    with tempfile.TemporaryDirectory(prefix="ropeload-chromium-") as profile:
        process = subprocess.Popen(
            [browser, *_FLAGS, f"--user-data-dir={profile}", "about:blank"],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            pass_fds=(3, 4),
            preexec_fn=wire_fds,  # the child's fds 3 and 4 before exec
        )
        os.close(to_browser_r)
        os.close(from_browser_w)
        pipe = _Pipe(to_browser_w, from_browser_r, timeout_s)
        try:
            return _capture(pipe, url, width, timeout_s, settle_s)
        finally:
            with contextlib.suppress(Exception):
                pipe.call("Browser.close")
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
            os.close(to_browser_w)
            os.close(from_browser_r)


def _capture(pipe: _Pipe, url: str, width: int, timeout_s: float, settle_s: float) -> Rendering:
    target = pipe.call("Target.createTarget", url="about:blank")["targetId"]
    session = pipe.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
    pipe.call("Page.enable", session)
    pipe.call("Network.enable", session)
    pipe.call(
        "Emulation.setDeviceMetricsOverride",
        session,
        width=width,
        height=1000,
        deviceScaleFactor=1,
        mobile=False,
    )
    pipe.call("Page.navigate", session, url=url)
    pipe.wait_event("Page.loadEventFired", timeout_s)
    end = time.monotonic() + timeout_s
    progress: dict = {}
    while time.monotonic() < end:
        progress = json.loads(str(pipe.evaluate(session, _PROGRESS)))
        if progress["drawn"] >= progress["figures"]:
            break
        time.sleep(0.25)
    else:
        raise TimeoutError(f"figures not drawn in {timeout_s:.0f} s: {progress}")
    time.sleep(settle_s)  # plotly's last relayout (legend, responsive width)
    progress = json.loads(str(pipe.evaluate(session, _PROGRESS)))
    height = int(progress["height"])
    pipe.call(
        "Emulation.setDeviceMetricsOverride",
        session,
        width=width,
        height=height,
        deviceScaleFactor=1,
        mobile=False,
    )
    time.sleep(settle_s)
    shot = pipe.call("Page.captureScreenshot", session, format="png", captureBeyondViewport=True)
    requests = [
        e["params"]["request"]["url"]
        for e in pipe.events
        if e.get("method") == "Network.requestWillBeSent"
    ]
    return Rendering(
        png=base64.b64decode(shot["data"]),
        width=width,
        height=height,
        figures=int(progress["figures"]),
        drawn=int(progress["drawn"]),
        with_data=int(progress["with_data"]),
        plotly_loaded=bool(progress["plotly"]),
        requests=requests,
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("report", type=Path, help="the report's HTML file")
    parser.add_argument("-o", "--output", type=Path, help="PNG to write (default: beside it)")
    parser.add_argument("--width", type=int, default=1400, help="page width [px]")
    parser.add_argument("--timeout", type=float, default=120.0, help="seconds to wait")
    args = parser.parse_args(argv)
    if not args.report.is_file():
        sys.stderr.write(f"screenshot_report: {args.report}: no such file\n")
        return 1
    try:
        result = render(args.report, width=args.width, timeout_s=args.timeout)
    except (FileNotFoundError, TimeoutError, ConnectionError, RuntimeError) as exc:
        sys.stderr.write(f"screenshot_report: {exc}\n")
        return 1
    output = args.output or args.report.with_suffix(".png")
    output.write_bytes(result.png)
    sys.stdout.write(
        f"{output}: {result.width} x {result.height} px; {result.drawn} of {result.figures} "
        f"figures drawn ({result.with_data} with data); plotly.js loaded: "
        f"{result.plotly_loaded}; requests outside the file: "
        f"{', '.join(result.external_requests) or 'none'}\n"
    )
    return 0 if result.drawn == result.figures and not result.external_requests else 1


if __name__ == "__main__":
    sys.exit(main())
