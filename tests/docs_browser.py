"""Headless Chromium for the site's tests, driven through the DevTools protocol over a pipe.

``chromium --remote-debugging-pipe`` reads protocol commands on file descriptor 3 and writes
replies and events on 4, each a JSON message ended by a NUL byte: no port, no websocket library,
nothing else to install (Debian's ``chromium`` package is the only dependency). :class:`Browser`
opens a page from ``file://``, waits until it has loaded and settled, and reports what a reader
would miss: console errors and uncaught exceptions, every request that left ``file://``, requests
that failed (a missing image, script or style sheet), images that did not decode, and equations
left as TeX. It writes a screenshot of the page.
"""

from __future__ import annotations

import base64
import json
import os
import select
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

#: Flags for a headless, quiet, offline-minded Chromium (as root in a container: no sandbox).
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--no-default-browser-check",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-extensions",
    "--disable-dev-shm-usage",
    "--hide-scrollbars",
    "--window-size=1280,1000",
)

#: Evaluated in the page once it has settled: what did not render.
_CHECK = """(() => {
  const images = Array.from(document.images)
    .filter(i => !i.complete || i.naturalWidth === 0).map(i => i.currentSrc || i.src);
  const maths = Array.from(document.querySelectorAll('math'));
  const flat = maths.filter(m => { const r = m.getBoundingClientRect(); return r.width === 0 || r.height === 0; });
  const text = document.body ? document.body.innerText : '';
  const tex = (text.match(/\\\\(frac|varepsilon|sigma|sum|left|right|qquad|mathrm)\\b|\\$\\$/g) || []);
  return {images: images, maths: maths.length, flat_maths: flat.length, tex: tex.slice(0, 5),
          title: document.title, text_length: text.length, ready: document.readyState};
})()"""


def find_chromium() -> str | None:
    """The Chromium executable (Debian's ``chromium``), or None."""
    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path
    return None


@dataclass
class PageReport:
    """What a reader of one page would have met."""

    url: str
    console_errors: list[str] = field(default_factory=list)
    external_requests: list[str] = field(default_factory=list)
    failed_requests: list[str] = field(default_factory=list)
    missing_images: list[str] = field(default_factory=list)
    maths: int = 0
    flat_maths: int = 0
    raw_tex: list[str] = field(default_factory=list)
    title: str = ""
    text_length: int = 0
    screenshot: Path | None = None

    def problems(self) -> list[str]:
        out = [f"console error: {e}" for e in self.console_errors]
        out += [f"request leaving file://: {u}" for u in self.external_requests]
        out += [f"failed request: {u}" for u in self.failed_requests]
        out += [f"image not shown: {u}" for u in self.missing_images]
        out += [f"{self.flat_maths} of {self.maths} equations have no size"] if self.flat_maths else []
        out += [f"equation left as TeX: {t}" for t in self.raw_tex]
        return out


class Browser:
    """One headless Chromium with a fresh profile; a context manager."""

    def __init__(self, executable: str, profile: Path | None = None):
        self.profile = Path(profile or tempfile.mkdtemp(prefix="dea-opt-chromium-"))
        to_browser_r, self._to_browser = os.pipe()
        self._from_browser, from_browser_w = os.pipe()

        def pipes_on_3_and_4() -> None:  # in the child, before exec: Chromium's fixed descriptors
            import fcntl

            read_end = fcntl.fcntl(to_browser_r, fcntl.F_DUPFD, 10)  # above 4, so neither is overwritten
            write_end = fcntl.fcntl(from_browser_w, fcntl.F_DUPFD, 10)
            os.dup2(read_end, 3)
            os.dup2(write_end, 4)

        self.process = subprocess.Popen(
            [executable, *FLAGS, f"--user-data-dir={self.profile}", "--remote-debugging-pipe"],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            close_fds=False,  # closing would close 3 and 4 too; Python's own descriptors close on exec
            preexec_fn=pipes_on_3_and_4,
        )
        os.close(to_browser_r)
        os.close(from_browser_w)
        self._buffer = b""
        self._next_id = 0
        self.events: list[dict] = []

    # --- the protocol ----------------------------------------------------------------------------
    def _send(self, method: str, params: dict | None = None, session: str | None = None) -> int:
        self._next_id += 1
        message = {"id": self._next_id, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = session
        os.write(self._to_browser, json.dumps(message).encode() + b"\0")
        return self._next_id

    def _read(self, timeout: float) -> dict | None:
        deadline = time.monotonic() + timeout
        while b"\0" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            ready, _, _ = select.select([self._from_browser], [], [], left)
            if not ready:
                return None
            chunk = os.read(self._from_browser, 1 << 20)
            if not chunk:
                raise RuntimeError("Chromium closed its pipe (it exited)")
            self._buffer += chunk
        message, _, self._buffer = self._buffer.partition(b"\0")
        return json.loads(message)

    def call(self, method: str, params: dict | None = None, session: str | None = None, timeout: float = 60.0):
        """Send a command and return its result; events that arrive meanwhile are kept."""
        wanted = self._send(method, params, session)
        deadline = time.monotonic() + timeout
        while True:
            message = self._read(max(0.0, deadline - time.monotonic()))
            if message is None:
                raise TimeoutError(f"Chromium did not answer {method} within {timeout} s")
            if message.get("id") == wanted:
                if "error" in message:
                    raise RuntimeError(f"{method}: {message['error']}")
                return message.get("result", {})
            if "method" in message:
                self.events.append(message)

    def _pump(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            message = self._read(max(0.0, deadline - time.monotonic()))
            if message is None:
                return
            if "method" in message:
                self.events.append(message)

    # --- pages -----------------------------------------------------------------------------------
    def open(self, url: str, screenshot: Path | None = None, settle: float = 1.0, timeout: float = 60.0) -> PageReport:
        """Load ``url`` in a new tab and report on it (and write a PNG screenshot)."""
        target = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        for domain in ("Page", "Runtime", "Log", "Network"):
            self.call(f"{domain}.enable", session=session)
        self.events = []
        self.call("Page.navigate", {"url": url}, session=session)
        deadline = time.monotonic() + timeout
        while not any(e.get("method") == "Page.loadEventFired" and e.get("sessionId") == session for e in self.events):
            if time.monotonic() > deadline:
                raise TimeoutError(f"{url} did not finish loading within {timeout} s")
            self._pump(0.2)
        self._pump(settle)
        check = self.call("Runtime.evaluate", {"expression": _CHECK, "returnByValue": True}, session=session)["result"][
            "value"
        ]
        report = PageReport(
            url=url,
            missing_images=check["images"],
            maths=check["maths"],
            flat_maths=check["flat_maths"],
            raw_tex=check["tex"],
            title=check["title"],
            text_length=check["text_length"],
        )
        for event in self.events:
            if event.get("sessionId") != session:
                continue
            method, params = event["method"], event.get("params", {})
            if method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
                report.console_errors.append(
                    " ".join(str(a.get("value", a.get("description"))) for a in params["args"])
                )
            elif method == "Runtime.exceptionThrown":
                details = params["exceptionDetails"]
                report.console_errors.append(details.get("exception", {}).get("description") or details.get("text", ""))
            elif method == "Log.entryAdded" and params["entry"]["level"] == "error":
                report.console_errors.append(f"{params['entry'].get('text')} ({params['entry'].get('url', '')})")
            elif method == "Network.requestWillBeSent":
                request_url = params["request"]["url"]
                if not request_url.startswith(("file:", "data:", "about:", "blob:")):
                    report.external_requests.append(request_url)
            elif method == "Network.loadingFailed" and not params.get("canceled"):
                report.failed_requests.append(f"{params.get('errorText')} ({params.get('type')})")
        if screenshot is not None:
            shot = self.call("Page.captureScreenshot", {"format": "png"}, session=session)["data"]
            screenshot.write_bytes(base64.b64decode(shot))
            report.screenshot = screenshot
        self.call("Target.closeTarget", {"targetId": target})
        return report

    def evaluate(self, url: str, expression: str, until: str, timeout: float = 30.0):
        """Open ``url``, wait until the JavaScript ``until`` is true, return ``expression``'s value."""
        target = self.call("Target.createTarget", {"url": url})["targetId"]
        session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        deadline = time.monotonic() + timeout
        try:
            while time.monotonic() < deadline:
                done = self.call(
                    "Runtime.evaluate", {"expression": f"!!({until})", "returnByValue": True}, session=session
                )
                if done.get("result", {}).get("value"):
                    break
                self._pump(0.25)
            value = self.call("Runtime.evaluate", {"expression": expression, "returnByValue": True}, session=session)
            return value["result"].get("value")
        finally:
            self.call("Target.closeTarget", {"targetId": target})

    def element_screenshot(self, url: str, selector: str, path: Path, until: str, timeout: float = 60.0) -> dict:
        """Open ``url``, wait until the JavaScript ``until`` is true, then write a PNG of the element
        ``selector`` (scrolled into view) to ``path``; returns its box ``{x, y, width, height}``."""
        target = self.call("Target.createTarget", {"url": url})["targetId"]
        session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        deadline = time.monotonic() + timeout
        try:
            while True:
                done = self.call(
                    "Runtime.evaluate", {"expression": f"!!({until})", "returnByValue": True}, session=session
                )
                if done.get("result", {}).get("value"):
                    break
                if time.monotonic() > deadline:
                    raise TimeoutError(f"{until} did not come true within {timeout} s on {url}")
                self._pump(0.25)
            self._pump(1.0)  # the first frames of a WebGL view
            where = (
                f"(() => {{ const e = document.querySelector({json.dumps(selector)}); e.scrollIntoView(); "
                "const r = e.getBoundingClientRect(); return {x: r.x + window.scrollX, y: r.y + window.scrollY, "
                "width: r.width, height: r.height}; })()"
            )
            box = self.call("Runtime.evaluate", {"expression": where, "returnByValue": True}, session=session)[
                "result"
            ]["value"]
            self._pump(0.5)
            shot = self.call(
                "Page.captureScreenshot",
                {"format": "png", "clip": {**box, "scale": 1}, "captureBeyondViewport": True},
                session=session,
            )["data"]
            Path(path).write_bytes(base64.b64decode(shot))
            return box
        finally:
            self.call("Target.closeTarget", {"targetId": target})

    def close(self) -> None:
        try:
            self.call("Browser.close", timeout=10.0)
        except (RuntimeError, TimeoutError, OSError):
            pass
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        for fd in (self._to_browser, self._from_browser):
            try:
                os.close(fd)
            except OSError:
                pass
        shutil.rmtree(self.profile, ignore_errors=True)

    def __enter__(self) -> Browser:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
