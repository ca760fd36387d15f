"""Drive headless Chromium through the DevTools protocol over a pipe (test helper).

``--remote-debugging-pipe`` makes Chromium read protocol commands from file
descriptor 3 and write replies and events to descriptor 4, each message a JSON
text ended by a NUL byte. That needs no websocket client and no extra Python
package. The page's errors are collected from the protocol's events: uncaught
exceptions (``Runtime.exceptionThrown``), ``console.error``/``console.assert``
calls (``Runtime.consoleAPICalled``) and browser log entries of level error
(``Log.entryAdded``: failed loads, blocked network requests, WebGL errors).
"""

from __future__ import annotations

import base64
import fcntl
import json
import os
import shutil
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

#: The flags the issue prescribes, plus the ones that keep a headless run from
#: reaching the network on its own.
CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-quic",
)


def find_chromium() -> str | None:
    """Path of the Chromium executable, or None."""
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    return None


class ChromiumError(RuntimeError):
    pass


def _fd_above(fd: int, minimum: int) -> int:
    """Duplicate ``fd`` to the lowest free number >= ``minimum``; close ``fd``."""
    if fd >= minimum:
        return fd
    high = fcntl.fcntl(fd, fcntl.F_DUPFD, minimum)
    os.close(fd)
    return high


class Chromium:
    """One headless Chromium with one page, driven over the DevTools pipe."""

    def __init__(
        self,
        executable: str,
        user_data_dir: Path,
        window_size: tuple[int, int] = (1280, 960),
        timeout: float = 60.0,
    ) -> None:
        self.timeout = timeout
        self.events: list[dict[str, Any]] = []
        self._replies: dict[int, dict[str, Any]] = {}
        self._cond = threading.Condition()
        self._next_id = 0
        self._closed = False
        # Pipe 1: we write, Chromium reads on fd 3. Pipe 2: Chromium writes fd 4.
        to_chrome_r, self._to_chrome_w = os.pipe()
        self._from_chrome_r, from_chrome_w = os.pipe()
        # Move the child's ends above 4 so that placing them on 3 and 4 below
        # cannot overwrite or close one another.
        to_chrome_r, from_chrome_w = (_fd_above(fd, 10) for fd in (to_chrome_r, from_chrome_w))
        args = [
            executable,
            *CHROMIUM_FLAGS,
            "--remote-debugging-pipe",
            f"--user-data-dir={user_data_dir}",
            f"--window-size={window_size[0]},{window_size[1]}",
            "about:blank",
        ]
        # bash moves the pipe ends to fds 3 and 4 before exec (no preexec_fn,
        # which is unsafe in a process that runs threads, as Meshcat's does;
        # bash, not sh, because dash cannot redirect fds above 9).
        script = (
            f'exec "$@" 3<&{to_chrome_r} 4>&{from_chrome_w} {to_chrome_r}<&- {from_chrome_w}>&-'
        )
        self.stderr_path = Path(user_data_dir) / "chromium-stderr.txt"
        self._stderr = open(self.stderr_path, "wb")
        self.process = subprocess.Popen(
            ["/bin/bash", "-c", script, "bash", *args],
            pass_fds=(to_chrome_r, from_chrome_w),
            stdin=subprocess.DEVNULL,
            stdout=self._stderr,
            stderr=self._stderr,
        )
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self._reader = threading.Thread(target=self._read_loop, daemon=True)
        self._reader.start()
        self.session_id: str | None = None
        try:
            self.session_id = self._attach_to_page()
        except BaseException:
            self.close()
            raise

    # -------------------------------------------------------------- transport
    def _read_loop(self) -> None:
        buffer = b""
        with os.fdopen(self._from_chrome_r, "rb", buffering=0) as pipe:
            while True:
                chunk = pipe.read(1 << 20)
                if not chunk:
                    break
                buffer += chunk
                while b"\0" in buffer:
                    raw, buffer = buffer.split(b"\0", 1)
                    message = json.loads(raw)
                    with self._cond:
                        if "id" in message:
                            self._replies[message["id"]] = message
                        else:
                            self.events.append(message)
                        self._cond.notify_all()
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    def send(
        self, method: str, params: dict[str, Any] | None = None, session: bool = True
    ) -> dict[str, Any]:
        """Send one command and wait for its result."""
        with self._cond:
            self._next_id += 1
            message_id = self._next_id
        message: dict[str, Any] = {"id": message_id, "method": method, "params": params or {}}
        if session and self.session_id:
            message["sessionId"] = self.session_id
        os.write(self._to_chrome_w, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + self.timeout
        with self._cond:
            while message_id not in self._replies:
                remaining = deadline - time.monotonic()
                if self._closed or remaining <= 0:
                    raise ChromiumError(f"no reply to {method}: {self.stderr_tail()}")
                self._cond.wait(remaining)
            reply = self._replies.pop(message_id)
        if "error" in reply:
            raise ChromiumError(f"{method} failed: {reply['error']}")
        return reply.get("result", {})

    def wait_for_event(self, method: str, timeout: float | None = None) -> dict[str, Any]:
        deadline = time.monotonic() + (timeout or self.timeout)
        with self._cond:
            while True:
                for event in self.events:
                    if event.get("method") == method:
                        return event
                remaining = deadline - time.monotonic()
                if self._closed or remaining <= 0:
                    raise ChromiumError(f"no {method} event: {self.stderr_tail()}")
                self._cond.wait(remaining)

    def stderr_tail(self, chars: int = 2000) -> str:
        try:
            return self.stderr_path.read_text(errors="replace")[-chars:]
        except OSError:
            return ""

    # ------------------------------------------------------------------ page
    def _attach_to_page(self) -> str:
        targets = self.send("Target.getTargets", session=False)["targetInfos"]
        pages = [t for t in targets if t["type"] == "page"]
        if pages:
            target_id = pages[0]["targetId"]
        else:
            target_id = self.send("Target.createTarget", {"url": "about:blank"}, False)["targetId"]
        result = self.send(
            "Target.attachToTarget", {"targetId": target_id, "flatten": True}, session=False
        )
        self.session_id = result["sessionId"]
        for domain in ("Page", "Runtime", "Log"):
            self.send(f"{domain}.enable")
        return self.session_id

    def set_viewport(self, width: int, height: int) -> None:
        """Make the page's viewport exactly ``width`` × ``height`` CSS pixels (scale 1)."""
        self.send(
            "Emulation.setDeviceMetricsOverride",
            {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False},
        )

    def navigate(self, url: str) -> None:
        """Load ``url`` and wait for its load event."""
        with self._cond:
            self.events = [e for e in self.events if e.get("method") != "Page.loadEventFired"]
        reply = self.send("Page.navigate", {"url": url})
        if reply.get("errorText"):
            raise ChromiumError(f"navigation to {url} failed: {reply['errorText']}")
        self.wait_for_event("Page.loadEventFired")

    def evaluate(self, expression: str, await_promise: bool = False) -> Any:
        """Value of a JavaScript expression in the page."""
        result = self.send(
            "Runtime.evaluate",
            {"expression": expression, "returnByValue": True, "awaitPromise": await_promise},
        )
        if "exceptionDetails" in result:
            raise ChromiumError(f"{expression!r} threw {result['exceptionDetails']}")
        return result["result"].get("value")

    def wait_until(self, expression: str, timeout: float | None = None) -> float:
        """Poll a JavaScript expression until it is true; returns the seconds waited."""
        start = time.monotonic()
        deadline = start + (timeout or self.timeout)
        while not self.evaluate(expression):
            if time.monotonic() > deadline:
                raise ChromiumError(f"timed out waiting for {expression!r}")
            time.sleep(0.1)
        return time.monotonic() - start

    def screenshot(self) -> bytes:
        """PNG of the viewport."""
        data = self.send("Page.captureScreenshot", {"format": "png"})["data"]
        return base64.b64decode(data)

    def page_errors(self) -> list[str]:
        """Every error the page reported so far, as readable lines."""
        errors = []
        with self._cond:
            events = list(self.events)
        for event in events:
            method, params = event.get("method"), event.get("params", {})
            if method == "Runtime.exceptionThrown":
                details = params.get("exceptionDetails", {})
                exception = details.get("exception", {})
                errors.append(f"uncaught: {exception.get('description') or details.get('text')}")
            elif method == "Runtime.consoleAPICalled" and params.get("type") in (
                "error",
                "assert",
            ):
                texts = [str(a.get("value", a.get("description", ""))) for a in params["args"]]
                errors.append(f"console.{params['type']}: {' '.join(texts)}")
            elif method == "Log.entryAdded" and params["entry"].get("level") == "error":
                entry = params["entry"]
                errors.append(
                    f"log {entry.get('source')}: {entry.get('text')} {entry.get('url', '')}"
                )
        return errors

    def console_messages(self) -> list[str]:
        """All console calls (any level), for diagnostics."""
        with self._cond:
            events = list(self.events)
        return [
            f"{e['params']['type']}: "
            + " ".join(str(a.get("value", a.get("description", ""))) for a in e["params"]["args"])
            for e in events
            if e.get("method") == "Runtime.consoleAPICalled"
        ]

    # --------------------------------------------------------------- cleanup
    def close(self) -> None:
        try:
            if self.process.poll() is None:
                try:
                    self.send("Browser.close", session=False)
                except ChromiumError:
                    pass
                try:
                    self.process.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    self.process.kill()
                    self.process.wait(timeout=10)
        finally:
            os.close(self._to_chrome_w)
            self._stderr.close()

    def __enter__(self) -> Chromium:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
