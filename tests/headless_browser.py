"""A real headless browser for tests: Debian's chromium driven over the DevTools protocol.

The protocol runs over `--remote-debugging-pipe` (JSON messages ended by a NUL byte on the browser's
file descriptors 3 and 4), so no WebSocket library and no network port are needed. `Browser.open(url)`
loads a page in a fresh tab and collects what the page reports as errors: uncaught exceptions
(Runtime.exceptionThrown), console.error / console.assert calls (Runtime.consoleAPICalled) and the
browser's own error entries (Log.entryAdded: a resource that failed to load, a blocked request).

    with Browser() as browser:
        page = browser.open('file:///tmp/x.html')
        page.evaluate('document.title'); page.screenshot(); page.errors
"""

from __future__ import annotations

import base64
import fcntl
import json
import os
import queue
import shutil
import subprocess
import tempfile
import threading
import time
from typing import Optional

CHROMIUM_FLAGS = ('--headless', '--no-sandbox', '--disable-gpu', '--no-first-run', '--no-default-browser-check',
                  '--disable-extensions', '--disable-background-networking', '--disable-sync', '--mute-audio')


def chromium_path() -> Optional[str]:
    """The chromium executable on PATH (Debian's package installs `chromium`), else None."""
    return shutil.which('chromium') or shutil.which('chromium-browser')


class BrowserError(RuntimeError):
    """The browser died, did not answer in time, or answered a command with an error."""


def blank_fraction(png: bytes) -> float:
    """How much of a screenshot is its most common colour (1.0: a blank picture)."""
    import io

    import numpy as np
    from PIL import Image
    pixels = np.asarray(Image.open(io.BytesIO(png)).convert('RGB')).reshape(-1, 3)
    _, counts = np.unique(pixels, axis=0, return_counts=True)
    return float(counts.max() / len(pixels))


def pixel_std(png: bytes) -> float:
    """The standard deviation of a screenshot's grey levels (0 for a blank picture)."""
    import io

    import numpy as np
    from PIL import Image
    return float(np.asarray(Image.open(io.BytesIO(png)).convert('L'), dtype=np.float64).std())


def screenshot_cli(url: str, out_png: str, size=(1200, 1600), timeout: float = 60.0) -> subprocess.CompletedProcess:
    """chromium's own one-shot screenshot (`--screenshot`) of `url`, as a person would run it."""
    exe = chromium_path()
    with tempfile.TemporaryDirectory(prefix='dialfred-chromium-') as profile:
        return subprocess.run([exe, *CHROMIUM_FLAGS, f'--user-data-dir={profile}', f'--screenshot={out_png}',
                               f'--window-size={size[0]},{size[1]}', '--hide-scrollbars', url],
                              stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=timeout)


class Page:
    """One tab attached over the browser's connection (a flat DevTools session)."""

    def __init__(self, browser: 'Browser', session_id: str):
        self.browser, self.session_id = browser, session_id

    def send(self, method: str, params: Optional[dict] = None, timeout: float = 30.0) -> dict:
        return self.browser.send(method, params, session_id=self.session_id, timeout=timeout)

    @property
    def errors(self) -> list[str]:
        """Every error the page reported so far, as text."""
        out = []
        for event in self.browser.events_of(self.session_id):
            method, params = event['method'], event.get('params', {})
            if method == 'Runtime.exceptionThrown':
                d = params['exceptionDetails']
                text = d.get('exception', {}).get('description') or d.get('text', '')
                out.append(f'uncaught exception: {text} ({d.get("url", "")}:{d.get("lineNumber", "?")})')
            elif method == 'Runtime.consoleAPICalled' and params.get('type') in ('error', 'assert'):
                args = ' '.join(str(a.get('value', a.get('description', ''))) for a in params.get('args', []))
                out.append(f'console.{params["type"]}: {args}')
            elif method == 'Log.entryAdded' and params['entry'].get('level') == 'error':
                e = params['entry']
                out.append(f'browser log ({e.get("source")}): {e.get("text")} {e.get("url", "")}'.rstrip())
        return out

    def evaluate(self, expression: str, timeout: float = 30.0):
        """The value of a JavaScript expression in the page (promises awaited); BrowserError if it throws."""
        reply = self.send('Runtime.evaluate', {'expression': expression, 'returnByValue': True,
                                               'awaitPromise': True}, timeout=timeout)
        if 'exceptionDetails' in reply:
            d = reply['exceptionDetails']
            raise BrowserError(f'{expression[:60]!r} threw: {d.get("exception", {}).get("description", d.get("text"))}')
        return reply['result'].get('value')

    def screenshot(self) -> bytes:
        """A PNG of the tab's viewport."""
        return base64.b64decode(self.send('Page.captureScreenshot', {'format': 'png'})['data'])


class Browser:
    """A headless chromium process and its DevTools connection; a context manager."""

    def __init__(self, size=(1200, 1600), timeout: float = 30.0):
        exe = chromium_path()
        if exe is None:
            raise BrowserError('no chromium on PATH')
        self.timeout, self.size = timeout, size
        self.profile = tempfile.mkdtemp(prefix='dialfred-chromium-')
        to_browser_r, to_browser_w = os.pipe()
        from_browser_r, from_browser_w = os.pipe()
        # the browser's ends, moved above 9 so that putting them on 3 and 4 cannot overwrite each other
        child_r, child_w = (fcntl.fcntl(fd, fcntl.F_DUPFD, 10) for fd in (to_browser_r, from_browser_w))
        for fd in (to_browser_r, from_browser_w):
            os.close(fd)
        command = (f'exec 3<&{child_r} 4>&{child_w} {child_r}<&- {child_w}>&-; exec "$0" "$@"')
        self.proc = subprocess.Popen(
            ['bash', '-c', command, exe, *CHROMIUM_FLAGS, '--remote-debugging-pipe', f'--user-data-dir={self.profile}',
             f'--window-size={size[0]},{size[1]}', '--hide-scrollbars', 'about:blank'],
            pass_fds=(child_r, child_w), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE)
        os.close(child_r)
        os.close(child_w)
        self._out = os.fdopen(to_browser_w, 'wb', buffering=0)
        self._in = os.fdopen(from_browser_r, 'rb', buffering=0)
        self._next_id = 0
        self._replies: dict[int, dict] = {}
        self._events: list[dict] = []
        self._inbox: queue.Queue = queue.Queue()
        self._stderr: list[bytes] = []
        threading.Thread(target=self._read, daemon=True).start()
        threading.Thread(target=lambda: self._stderr.extend(self.proc.stderr), daemon=True).start()
        self.send('Browser.getVersion')

    # the connection --------------------------------------------------------------------------------
    def _read(self) -> None:
        buffer = b''
        while True:
            chunk = self._in.read(65536)
            if not chunk:
                self._inbox.put(None)
                return
            buffer += chunk
            *messages, buffer = buffer.split(b'\0')
            for m in messages:
                self._inbox.put(json.loads(m))

    def _pump(self, deadline: float) -> None:
        """Take one message off the connection (waiting at most until `deadline`)."""
        try:
            message = self._inbox.get(timeout=max(0.01, deadline - time.monotonic()))
        except queue.Empty:
            return
        if message is None:
            raise BrowserError(f'chromium closed the connection (exit code {self.proc.poll()}): '
                               f'{b"".join(self._stderr[-20:]).decode(errors="replace")[-2000:]}')
        if 'id' in message:
            self._replies[message['id']] = message
        else:
            self._events.append(message)

    def send(self, method: str, params: Optional[dict] = None, session_id: Optional[str] = None,
             timeout: Optional[float] = None) -> dict:
        """Send a command and wait for its reply's result; BrowserError for an error reply or no reply."""
        self._next_id += 1
        message = {'id': self._next_id, 'method': method, 'params': params or {}}
        if session_id:
            message['sessionId'] = session_id
        self._out.write(json.dumps(message).encode() + b'\0')
        deadline = time.monotonic() + (timeout or self.timeout)
        while self._next_id not in self._replies:
            if time.monotonic() > deadline:
                raise BrowserError(f'no reply to {method} in {timeout or self.timeout} s')
            self._pump(deadline)
        reply = self._replies.pop(self._next_id)
        if 'error' in reply:
            raise BrowserError(f'{method}: {reply["error"].get("message")} {reply["error"].get("data", "")}'.rstrip())
        return reply.get('result', {})

    def events_of(self, session_id: str) -> list[dict]:
        return [e for e in self._events if e.get('sessionId') == session_id]

    def wait_for_event(self, session_id: str, method: str, timeout: Optional[float] = None) -> dict:
        deadline = time.monotonic() + (timeout or self.timeout)
        seen = 0
        while True:
            events = self.events_of(session_id)
            for e in events[seen:]:
                if e['method'] == method:
                    return e
            seen = len(events)
            if time.monotonic() > deadline:
                raise BrowserError(f'no {method} in {timeout or self.timeout} s')
            self._pump(deadline)

    # pages -----------------------------------------------------------------------------------------
    def open(self, url: str, settle_s: float = 0.3) -> Page:
        """A new tab that has loaded `url` (its load event fired), with error collection on from the start."""
        target = self.send('Target.createTarget', {'url': 'about:blank'})['targetId']
        session = self.send('Target.attachToTarget', {'targetId': target, 'flatten': True})['sessionId']
        page = Page(self, session)
        for domain in ('Page', 'Runtime', 'Log'):
            page.send(f'{domain}.enable')
        page.send('Emulation.setDeviceMetricsOverride', {'width': self.size[0], 'height': self.size[1],
                                                         'deviceScaleFactor': 1, 'mobile': False})
        page.send('Page.navigate', {'url': url})
        self.wait_for_event(session, 'Page.loadEventFired')
        end = time.monotonic() + settle_s          # late errors (a timer, a lazy image) still arrive
        while time.monotonic() < end:
            self._pump(end)
        return page

    def close(self) -> None:
        try:
            if self.proc.poll() is None:
                try:
                    self.send('Browser.close', timeout=5)
                except BrowserError:
                    pass
                try:
                    self.proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    self.proc.kill()
                    self.proc.wait()
        finally:
            self._out.close()
            shutil.rmtree(self.profile, ignore_errors=True)

    def __enter__(self) -> 'Browser':
        return self

    def __exit__(self, *exc) -> None:
        self.close()
