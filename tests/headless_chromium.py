"""A minimal client of headless Chromium over the DevTools protocol on a pipe (no network
port, no extra package): load a page, evaluate JavaScript, collect console errors, take
screenshots. Used by the web player's tests."""

from __future__ import annotations

import base64
import fcntl
import json
import os
import shutil
import subprocess
import tempfile
import time
from collections.abc import Iterator

import pytest

#: Executables tried, in order (Debian's package is ``chromium``).
EXECUTABLES = ("chromium", "chromium-browser", "google-chrome")

FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--enable-unsafe-swiftshader",
    "--use-angle=swiftshader",
    "--mute-audio",
)


#: The web player has loaded and drawn two frames since (a screenshot then shows the loaded
#: signer): the ``ready`` expression for :meth:`Chromium.open`.
READY = "window.azeePlayer && azeePlayer.ready && azeePlayer.frames > azeePlayer.readyFrame + 2"


def launched(size: tuple[int, int]) -> Iterator[Chromium]:
    """A browser whose page is ``size`` pixels, for a fixture to ``yield from`` (closed after
    its last test); skips the tests when no Chromium is installed."""
    exe = find_chromium()
    if exe is None:
        pytest.skip("no chromium here (Debian: apt-get install chromium)")
    b = Chromium(exe, size=size)
    yield b
    b.close()


def find_chromium() -> str | None:
    """The path of a Chromium executable, or None."""
    for name in EXECUTABLES:
        path = shutil.which(name)
        if path:
            return path
    return None


class Chromium:
    """One headless browser with one page, driven over ``--remote-debugging-pipe``."""

    def __init__(self, executable: str, size: tuple[int, int] = (640, 480)):
        self.profile = tempfile.mkdtemp(prefix="azee-chromium-")
        r_cmd, w_cmd = os.pipe()  # our commands -> the browser's fd 3
        r_res, w_res = os.pipe()  # the browser's fd 4 -> our replies
        # the child's ends above fd 9, so that putting them on 3 and 4 overwrites neither
        for fd in (r_cmd, w_res):
            high = fcntl.fcntl(fd, fcntl.F_DUPFD, 10)
            os.close(fd)
            r_cmd, w_res = (high, w_res) if fd == r_cmd else (r_cmd, high)

        # the browser reads commands on fd 3 and writes replies on fd 4: a shell puts the
        # pipe ends there (bash: dash takes no fd above 9) and execs it
        self.proc = subprocess.Popen(
            [
                "bash",
                "-c",
                f'exec "$@" 3<&{r_cmd} 4>&{w_res}',
                "bash",
                executable,
                *FLAGS,
                f"--user-data-dir={self.profile}",
                "--remote-debugging-pipe",
                f"--window-size={size[0]},{size[1]}",
                "about:blank",
            ],
            pass_fds=(r_cmd, w_res),
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        os.close(r_cmd)
        os.close(w_res)
        self._w = os.fdopen(w_cmd, "wb", buffering=0)
        self._r = os.fdopen(r_res, "rb", buffering=0)
        self._buf, self._id, self.events = b"", 0, []
        page = next(t for t in self.send("Target.getTargets")["targetInfos"] if t["type"] == "page")
        self.session = self.send(
            "Target.attachToTarget", {"targetId": page["targetId"], "flatten": True}
        )["sessionId"]
        for domain in ("Runtime", "Log", "Page"):
            self.send(f"{domain}.enable", session=True)
        self.send(
            "Emulation.setDeviceMetricsOverride",
            {"width": size[0], "height": size[1], "deviceScaleFactor": 1, "mobile": False},
            session=True,
        )

    def _message(self) -> dict:
        while b"\0" not in self._buf:
            chunk = self._r.read(1 << 16)
            if not chunk:
                raise RuntimeError("chromium closed its DevTools pipe")
            self._buf += chunk
        msg, self._buf = self._buf.split(b"\0", 1)
        return json.loads(msg)

    def send(self, method: str, params: dict | None = None, session: bool = False) -> dict:
        """Send one DevTools command and return its result (events are kept in ``events``)."""
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = self.session
        self._w.write(json.dumps(msg).encode() + b"\0")
        while True:
            reply = self._message()
            if reply.get("id") == self._id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            self.events.append(reply)

    def evaluate(self, expression: str):
        """The value of a JavaScript expression in the page."""
        r = self.send(
            "Runtime.evaluate", {"expression": expression, "returnByValue": True}, session=True
        )
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expression}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def open(self, url: str, ready: str, timeout: float = 60.0) -> None:
        """Navigate to ``url`` and wait until the expression ``ready`` is true."""
        self.evaluate("window.__stale = true")  # gone once the new document replaces it
        self.send("Page.navigate", {"url": url}, session=True)
        self.open_wait(f"!window.__stale && ({ready})", timeout, url)

    def open_wait(self, ready: str, timeout: float = 60.0, where: str = "page") -> None:
        """Wait until the expression ``ready`` is true in the current page."""
        end = time.monotonic() + timeout
        while not self.evaluate(f"!!({ready})"):
            if time.monotonic() > end:
                raise TimeoutError(f"{where}: {ready} still false after {timeout} s")
            time.sleep(0.05)

    def errors(self) -> list[str]:
        """Console errors, uncaught exceptions and error log entries seen so far."""
        out = []
        for e in self.events:
            m, p = e.get("method"), e.get("params", {})
            if m == "Runtime.exceptionThrown":
                out.append(json.dumps(p["exceptionDetails"])[:500])
            elif m == "Runtime.consoleAPICalled" and p["type"] in ("error", "assert"):
                out.append(" ".join(str(a.get("value", a.get("description"))) for a in p["args"]))
            elif m == "Log.entryAdded" and p["entry"]["level"] == "error":
                out.append(p["entry"]["text"])
        return out

    def screenshot(self) -> bytes:
        """The page as PNG bytes."""
        return base64.b64decode(
            self.send("Page.captureScreenshot", {"format": "png"}, session=True)["data"]
        )

    def close(self) -> None:
        """Close the browser and remove its profile."""
        try:
            self.send("Browser.close")
        except (RuntimeError, OSError):
            pass
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self._w.close()
        self._r.close()
        shutil.rmtree(self.profile, ignore_errors=True)
