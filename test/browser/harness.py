"""
The live view in a real browser, for tests: Foxglove Studio 1.48 in headless Chromium.

Everything runs on loopback and installs itself once:

- :func:`ensure_studio`: npm's ``@foxglove/studio-base@1.48.0`` (MPL-2.0, the
  last open-source Studio, a prebuilt bundle) with React 17, cached in
  ``~/.cache/r2d2_sim/foxglove-studio-1.48.0/`` (about 11 s and 180 MB the
  first time).
- :func:`ensure_chromium`: Debian's ``chromium`` (``apt-get install -y
  chromium`` when running as root and it is missing; about a minute).
- :class:`StaticServer`: serves ``index.html`` and ``host.js`` from this
  directory, the seeded layout ``config/foxglove_layout.json``, the npm
  packages, and optionally a directory of recordings (with HTTP ranges, for
  ``?ds=remote-file``).
- :class:`Relay`: Studio 1.48 speaks only the ``foxglove.websocket.v1``
  subprotocol and foxglove-sdk 0.30 only ``foxglove.sdk.v1``; the
  protocols are otherwise the same, so frames are passed through unchanged.
- :class:`Chromium`: headless Chromium with SwiftShader WebGL, driven over
  the DevTools protocol with the ``websockets`` package.
"""

import base64
import fcntl
import http.server
import itertools
import json
import os
from pathlib import Path
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from contextlib import ExitStack
from typing import Any, Dict, Optional
import urllib.request

from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect
from websockets.sync.server import serve

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
LAYOUT_PATH = REPO / 'config' / 'foxglove_layout.json'
STUDIO_VERSION = '1.48.0'
NPM_PACKAGES = [f'@foxglove/studio-base@{STUDIO_VERSION}', 'react@17.0.2', 'react-dom@17.0.2']
STUDIO_SUBPROTOCOL = 'foxglove.websocket.v1'
SDK_SUBPROTOCOL = 'foxglove.sdk.v1'
# Flags for a root user on a machine with no GPU and no network beyond loopback:
# no sandbox (root), WebGL through SwiftShader for the 3D panel, and none of
# the background requests that a closed network refuses. --disable-gpu is
# left out: Chromium 156 gave WebGL 2 on SwiftShader with and without it.
CHROMIUM_FLAGS = [
    '--headless=new', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    '--no-first-run', '--no-default-browser-check', '--disable-background-networking',
    '--disable-component-update', '--disable-sync', '--disable-default-apps',
    '--disable-extensions', '--mute-audio', '--hide-scrollbars',
]


class HarnessUnavailable(RuntimeError):
    """This machine cannot run the browser harness (no npm, no Chromium and no way to install)."""


def free_port() -> int:
    """Return a loopback TCP port nothing listens on now (a server binds it a moment later)."""
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]


def cache_dir() -> Path:
    """Return where the npm packages go: ``$XDG_CACHE_HOME/r2d2_sim/foxglove-studio-1.48.0``."""
    base = Path(os.environ.get('XDG_CACHE_HOME') or Path.home() / '.cache')
    return base / 'r2d2_sim' / f'foxglove-studio-{STUDIO_VERSION}'


def ensure_studio(timeout_s: float = 900.0) -> Path:
    """
    Return the directory whose ``node_modules`` holds Studio 1.48 and React 17, installing once.

    Installs into a temporary directory and renames it, under a lock, so an
    interrupted or concurrent install never leaves a half-filled cache.
    """
    target = cache_dir()
    marker = target / '.installed'
    if marker.is_file():
        return target
    npm = shutil.which('npm')
    if npm is None:
        raise HarnessUnavailable('npm is not installed (Debian: apt-get install npm)')
    target.parent.mkdir(parents=True, exist_ok=True)
    with open(target.parent / f'.{target.name}.lock', 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if marker.is_file():
            return target
        work = Path(tempfile.mkdtemp(prefix=target.name + '.', dir=target.parent))
        try:
            (work / 'package.json').write_text(json.dumps(
                {'name': 'r2d2-sim-foxglove-harness', 'private': True}))
            result = subprocess.run(
                [npm, 'install', '--no-audit', '--no-fund', '--ignore-scripts',
                 '--loglevel=error', *NPM_PACKAGES],
                cwd=work, capture_output=True, text=True, timeout=timeout_s)
            bundle = work / 'node_modules' / '@foxglove' / 'studio-base' / 'assets' / 'index.js'
            if result.returncode != 0 or not bundle.is_file():
                raise HarnessUnavailable(f'npm install {" ".join(NPM_PACKAGES)} failed: '
                                         f'{result.stderr.strip()[-500:]}')
            (work / '.installed').write_text(' '.join(NPM_PACKAGES) + '\n')
            if target.exists():
                shutil.rmtree(target)
            os.replace(work, target)
        finally:
            if work.exists():
                shutil.rmtree(work)
    return target


def ensure_chromium(timeout_s: float = 900.0) -> str:
    """Return the path of Chromium, installing Debian's package when root and it is missing."""
    for name in ('chromium', 'chromium-browser'):
        found = shutil.which(name)
        if found:
            return found
    apt = shutil.which('apt-get')
    if os.geteuid() != 0 or apt is None:
        raise HarnessUnavailable('Chromium is not installed (Debian: apt-get install chromium)')
    env = dict(os.environ, DEBIAN_FRONTEND='noninteractive')
    for command in ([apt, 'update', '-qq'], [apt, 'install', '-y', '-qq', 'chromium']):
        result = subprocess.run(command, env=env, capture_output=True, text=True,
                                timeout=timeout_s)
        if result.returncode != 0:
            raise HarnessUnavailable(f'{" ".join(command)} failed: {result.stderr.strip()[-500:]}')
    found = shutil.which('chromium')
    if found is None:
        raise HarnessUnavailable('apt-get installed chromium, but it is not on PATH')
    return found


class StaticServer:
    """
    A loopback HTTP server for the host page, the layout, the npm packages and recordings.

    ``/`` and ``/index.html``, ``/host.js``: this directory; ``/layout.json``:
    the layout users get; ``/node_modules/...``: the cache; ``/files/...``:
    ``files_dir``, with ``Range`` requests (Studio reads MCAP files in parts).
    """

    def __init__(self, studio_dir: Path, files_dir: Optional[Path] = None) -> None:
        routes = {
            '/index.html': HERE / 'index.html', '/host.js': HERE / 'host.js',
            '/layout.json': LAYOUT_PATH,
        }
        prefixes = {'/node_modules/': Path(studio_dir) / 'node_modules'}
        if files_dir is not None:
            prefixes['/files/'] = Path(files_dir)

        class Handler(_RangeHandler):
            def translate_path(self, path):
                path = path.split('?', 1)[0].split('#', 1)[0]
                if path == '/':
                    path = '/index.html'
                if path in routes:
                    return str(routes[path])
                for prefix, root in prefixes.items():
                    if path.startswith(prefix):
                        relative = Path(urllib.request.url2pathname(path[len(prefix):]))
                        resolved = (root / relative).resolve()
                        if root.resolve() in resolved.parents:
                            return str(resolved)
                return str(HERE / '.missing')

        self._server = _QuietServer(('127.0.0.1', 0), Handler)
        self.port = self._server.server_address[1]
        self._thread = threading.Thread(target=self._server.serve_forever, daemon=True)
        self._thread.start()

    def url(self, path: str = '/') -> str:
        """Return the address of ``path`` on this server."""
        return f'http://127.0.0.1:{self.port}{path}'

    def close(self) -> None:
        """Stop serving."""
        self._server.shutdown()
        self._server.server_close()


class _QuietServer(http.server.ThreadingHTTPServer):
    """A threading HTTP server that does not print a traceback when a browser hangs up."""

    daemon_threads = True

    def handle_error(self, request, client_address):
        if not isinstance(sys.exc_info()[1], ConnectionError):
            super().handle_error(request, client_address)


class _RangeHandler(http.server.SimpleHTTPRequestHandler):
    """SimpleHTTPRequestHandler plus single-range ``Range: bytes=a-b`` requests, quietly."""

    extensions_map = {**http.server.SimpleHTTPRequestHandler.extensions_map,
                      '.js': 'application/javascript', '.wasm': 'application/wasm',
                      '.mcap': 'application/octet-stream'}

    def send_head(self):
        match = re.fullmatch(r'bytes=(\d*)-(\d*)', self.headers.get('Range', ''))
        path = self.translate_path(self.path)
        if match is None or not os.path.isfile(path):
            return super().send_head()
        size = os.path.getsize(path)
        first, last = match.groups()
        start = int(first) if first else max(size - int(last or 0), 0)
        end = min(int(last), size - 1) if first and last else size - 1
        if start > end:
            self.send_error(416)
            return None
        stream = open(path, 'rb')
        stream.seek(start)
        self.send_response(206)
        self.send_header('Content-Type', self.guess_type(path))
        self.send_header('Content-Range', f'bytes {start}-{end}/{size}')
        self.send_header('Content-Length', str(end - start + 1))
        self.send_header('Accept-Ranges', 'bytes')
        self.end_headers()
        self._remaining = end - start + 1
        return stream

    def copyfile(self, source, outputfile):
        remaining = getattr(self, '_remaining', None)
        if remaining is None:
            return super().copyfile(source, outputfile)
        while remaining > 0:
            chunk = source.read(min(remaining, 1 << 16))
            if not chunk:
                break
            outputfile.write(chunk)
            remaining -= len(chunk)

    def end_headers(self):
        self.send_header('Accept-Ranges', 'bytes')
        self.send_header('Cache-Control', 'no-store')
        super().end_headers()

    def log_message(self, format, *args):
        pass


class Relay:
    """A loopback WebSocket server for Studio 1.48 that passes frames to foxglove-sdk and back."""

    def __init__(self, upstream_port: int) -> None:
        upstream = f'ws://127.0.0.1:{upstream_port}'

        def handle(client):
            try:
                with connect(upstream, subprotocols=[SDK_SUBPROTOCOL], max_size=None) as server:
                    forward = threading.Thread(target=_pump, args=(client, server), daemon=True)
                    forward.start()
                    _pump(server, client)
            except (OSError, ConnectionClosed):
                pass

        self._server = serve(handle, '127.0.0.1', 0, subprotocols=[STUDIO_SUBPROTOCOL],
                             max_size=None, compression=None)
        self.port = self._server.socket.getsockname()[1]
        self._thread = threading.Thread(target=self._server.serve_forever, daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        """Return the address Studio connects to."""
        return f'ws://127.0.0.1:{self.port}'

    def close(self) -> None:
        """Stop accepting and end the connections."""
        self._server.shutdown()


def _pump(source, destination) -> None:
    """Copy frames (text or binary) from one connection to the other until either closes."""
    try:
        for frame in source:
            destination.send(frame)
    except (OSError, ConnectionClosed):
        pass
    finally:
        source.close()
        destination.close()


class Chromium:
    """Headless Chromium on ``url``, driven over the DevTools protocol."""

    def __init__(self, binary: str, url: str, width: int = 1600, height: int = 1000,
                 timeout_s: float = 30.0) -> None:
        self._profile = Path(tempfile.mkdtemp(prefix='r2d2-chromium-'))
        self._log = open(self._profile / 'chromium.log', 'wb')
        self.process = subprocess.Popen(
            [binary, *CHROMIUM_FLAGS, f'--user-data-dir={self._profile}',
             '--remote-debugging-port=0', f'--window-size={width},{height}', url],
            stdout=self._log, stderr=subprocess.STDOUT)
        self._ids = itertools.count(1)
        self._connection = ExitStack()
        self._ws = None
        try:
            port = self._devtools_port(timeout_s)
            with urllib.request.urlopen(f'http://127.0.0.1:{port}/json/list',
                                        timeout=timeout_s) as reply:
                targets = json.load(reply)
            page = next(t for t in targets if t.get('type') == 'page')
            self._ws = self._connection.enter_context(connect(
                page['webSocketDebuggerUrl'], max_size=None, open_timeout=timeout_s))
            self.call('Runtime.enable')
        except BaseException:
            self.close()
            raise

    def _devtools_port(self, timeout_s: float) -> int:
        """Read the port Chromium chose from the profile's DevToolsActivePort file."""
        path = self._profile / 'DevToolsActivePort'
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.process.poll() is not None:
                raise HarnessUnavailable(f'Chromium exited with {self.process.returncode}: '
                                         f'{self.log_tail()}')
            if path.is_file():
                text = path.read_text().split()
                if text:
                    return int(text[0])
            time.sleep(0.05)
        raise HarnessUnavailable(f'Chromium opened no DevTools port in {timeout_s:g} s')

    def call(self, method: str, timeout_s: float = 60.0, **params) -> Dict[str, Any]:
        """Send one DevTools command and return its result (events are skipped)."""
        request_id = next(self._ids)
        self._ws.send(json.dumps({'id': request_id, 'method': method, 'params': params}))
        deadline = time.monotonic() + timeout_s
        while True:
            reply = json.loads(self._ws.recv(timeout=max(deadline - time.monotonic(), 0.001)))
            if reply.get('id') == request_id:
                if 'error' in reply:
                    raise RuntimeError(f'{method}: {reply["error"]}')
                return reply['result']

    def evaluate(self, expression: str) -> Any:
        """Evaluate JavaScript in the page (awaiting a promise) and return its JSON value."""
        result = self.call('Runtime.evaluate', expression=expression, returnByValue=True,
                           awaitPromise=True)
        if 'exceptionDetails' in result:
            raise RuntimeError(f'{expression[:80]}...: {result["exceptionDetails"]}')
        return result['result'].get('value')

    def wait_for(self, expression: str, timeout_s: float, poll_s: float = 0.5) -> Any:
        """Evaluate ``expression`` until it is truthy; return it (or the last value at the end)."""
        deadline = time.monotonic() + timeout_s
        while True:
            value = self.evaluate(expression)
            if value or time.monotonic() > deadline:
                return value
            time.sleep(poll_s)

    def screenshot(self, clip: Optional[Dict[str, float]] = None) -> bytes:
        """Return a PNG of the page, or of ``clip`` (x, y, width, height in CSS pixels)."""
        params = {'format': 'png'}
        if clip is not None:
            params['clip'] = {**clip, 'scale': 1}
        return base64.b64decode(self.call('Page.captureScreenshot', **params)['data'])

    def log_tail(self, lines: int = 20) -> str:
        """Return the end of Chromium's own output."""
        self._log.flush()
        text = (self._profile / 'chromium.log').read_text(errors='replace').splitlines()
        return '\n'.join(text[-lines:])

    def close(self) -> None:
        """End the browser and remove its profile; safe to call again."""
        self._connection.close()
        self._ws = None
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._log.close()
        shutil.rmtree(self._profile, ignore_errors=True)

    def __enter__(self) -> 'Chromium':
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()
