#!/usr/bin/env python3
"""Opens one tdpcr HTML view in headless chromium (DevTools protocol over a pipe, no
Python packages needed), waits until plotly has drawn it, fails on any console error or
uncaught exception, takes a screenshot and checks that something is drawn inside the
expected region (non-background pixels). Prints the time to first render.

usage: check_page.py CHROMIUM PAGE.html SCREENSHOT.png [--region X0,Y0,X1,Y1] [--min-fraction F]
Region in fractions of the 1200 x 800 window (default: the plot area 0.05,0.1,0.75,0.9).
A chromium that exits before it opens a tab is started again (three launches in all);
chromium's own messages are appended to the file $CHROMIUM_LOG if set.
"""

import argparse
import base64
import json
import os
import struct
import subprocess
import sys
import tempfile
import time
import zlib

WIDTH, HEIGHT = 1200, 800
TIMEOUT_S = 90.0
# Launches of chromium before a tab opens (see `open_tab`).
STARTUP_ATTEMPTS = 3


class Browser:
    """chromium with --remote-debugging-pipe: requests on fd 3, replies on fd 4, NUL-ended."""

    def __init__(self, chromium):
        self.profile = tempfile.mkdtemp(prefix="tdpcr-chromium-")
        to_browser_r, self.to_browser = os.pipe()
        self.from_browser, from_browser_w = os.pipe()

        def child_fds():
            # Through fresh descriptors first: dup2 onto itself would keep close-on-exec.
            r, w = os.dup(to_browser_r), os.dup(from_browser_w)
            os.dup2(r, 3)
            os.dup2(w, 4)

        flags = [
            "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
            "--disable-background-networking", "--disable-component-update", "--disable-sync",
            "--enable-unsafe-swiftshader", "--use-angle=swiftshader",
            "--remote-debugging-pipe", f"--user-data-dir={self.profile}",
            f"--window-size={WIDTH},{HEIGHT}", "about:blank",
        ]
        self.proc = subprocess.Popen(
            [chromium, *flags], preexec_fn=child_fds, close_fds=False,
            stdout=subprocess.DEVNULL, stderr=open(os.environ.get("CHROMIUM_LOG", os.devnull), "a"),
        )
        os.close(to_browser_r)
        os.close(from_browser_w)
        self.buffer = b""
        self.next_id = 0
        self.events = []

    def send(self, method, params=None, session=None):
        self.next_id += 1
        msg = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self.to_browser, json.dumps(msg).encode() + b"\0")
        while True:
            reply = self.read()
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            self.events.append(reply)

    def read(self):
        while b"\0" not in self.buffer:
            chunk = os.read(self.from_browser, 1 << 20)
            if not chunk:
                raise RuntimeError("chromium closed the DevTools pipe")
            self.buffer += chunk
        msg, self.buffer = self.buffer.split(b"\0", 1)
        return json.loads(msg)

    def close(self):
        try:
            self.send("Browser.close")
        except Exception:
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        subprocess.run(["rm", "-rf", self.profile])


def console_errors(events):
    """Console errors, uncaught exceptions and error log entries among the events."""
    errors = []
    for e in events:
        m, p = e.get("method"), e.get("params", {})
        if m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
            errors.append("console." + p["type"] + ": " + " ".join(
                str(a.get("value", a.get("description", ""))) for a in p.get("args", [])))
        elif m == "Runtime.exceptionThrown":
            d = p.get("exceptionDetails", {})
            errors.append("exception: " + d.get("exception", {}).get("description", d.get("text", "")))
        elif m == "Log.entryAdded" and p.get("entry", {}).get("level") == "error":
            entry = p["entry"]
            # WebGL performance notes of the software renderer ("GPU stall due to
            # ReadPixels") are logged at error level by chromium, but are not page errors.
            if "GPU stall due to ReadPixels" in entry.get("text", ""):
                continue
            errors.append(f"log {entry.get('source')}: {entry.get('text')} {entry.get('url', '')}")
    return errors


def decode_png(data):
    """(width, height, rows of RGB(A) bytes) of an 8-bit RGB or RGBA PNG."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    pos, idat, header = 8, b"", None
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind = data[pos + 4:pos + 8]
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    width, height, depth, colour, _, _, interlace = header
    assert depth == 8 and colour in (2, 6) and interlace == 0, f"unsupported PNG {header}"
    bpp = 3 if colour == 2 else 4
    raw = zlib.decompress(idat)
    stride = width * bpp
    rows, prev = [], bytearray(stride)
    for y in range(height):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for x in range(stride):
            a = line[x - bpp] if x >= bpp else 0
            b = prev[x]
            c = prev[x - bpp] if x >= bpp else 0
            if f == 1:
                line[x] = (line[x] + a) & 255
            elif f == 2:
                line[x] = (line[x] + b) & 255
            elif f == 3:
                line[x] = (line[x] + (a + b) // 2) & 255
            elif f == 4:
                pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                pr = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                line[x] = (line[x] + pr) & 255
        rows.append(bytes(line))
        prev = line
    return width, height, bpp, rows


def drawn_fraction(png, region):
    """Fraction of pixels in region (fractions x0,y0,x1,y1) that are not near-white."""
    width, height, bpp, rows = decode_png(png)
    x0, y0, x1, y1 = (int(f * n) for f, n in zip(region, (width, height, width, height)))
    drawn = total = 0
    for y in range(y0, y1, 2):
        row = rows[y]
        for x in range(x0, x1, 2):
            r, g, b = row[x * bpp], row[x * bpp + 1], row[x * bpp + 2]
            total += 1
            if min(r, g, b) < 200:
                drawn += 1
    return drawn / max(total, 1)


def open_tab(chromium, attempts=STARTUP_ATTEMPTS):
    """A started chromium and the session of a blank tab in it. A chromium that exits
    before it answers the first command (a fresh-clone CI run once lost one so, at the
    fourth of four launches, with no page loaded yet) is started again, saying so, up to
    `attempts` times in all; a failure once a page is loaded is never retried."""
    for attempt in range(1, attempts + 1):
        browser = Browser(chromium)
        try:
            target = browser.send("Target.createTarget", {"url": "about:blank"})["targetId"]
            session = browser.send("Target.attachToTarget",
                                   {"targetId": target, "flatten": True})["sessionId"]
            return browser, session
        except RuntimeError as e:
            browser.close()
            if attempt == attempts:
                raise
            print(f"chromium did not start (attempt {attempt}: {e}, exit code "
                  f"{browser.proc.returncode}); starting it again", file=sys.stderr)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("chromium")
    ap.add_argument("page")
    ap.add_argument("screenshot")
    ap.add_argument("--region", default="0.05,0.1,0.75,0.9")
    ap.add_argument("--min-fraction", type=float, default=0.01)
    args = ap.parse_args()
    region = [float(x) for x in args.region.split(",")]
    url = "file://" + os.path.abspath(args.page)
    browser, session = open_tab(args.chromium)
    try:
        for domain in ("Runtime", "Log", "Page"):
            browser.send(f"{domain}.enable", session=session)
        browser.send("Emulation.setDeviceMetricsOverride",
                     {"width": WIDTH, "height": HEIGHT, "deviceScaleFactor": 1, "mobile": False},
                     session=session)
        start = time.monotonic()
        browser.send("Page.navigate", {"url": url}, session=session)
        rendered = False
        while time.monotonic() - start < TIMEOUT_S:
            r = browser.send("Runtime.evaluate",
                             {"expression": "document.body && document.body.dataset.rendered || ''",
                              "returnByValue": True}, session=session)
            if r.get("result", {}).get("value") == "yes":
                rendered = True
                break
            if console_errors(browser.events):
                break
            time.sleep(0.05)
        render_s = time.monotonic() - start
        time.sleep(0.5)  # let WebGL finish the frame and late errors arrive
        shot = browser.send("Page.captureScreenshot", {"format": "png"}, session=session)
        png = base64.b64decode(shot["data"])
        with open(args.screenshot, "wb") as f:
            f.write(png)
        errors = console_errors(browser.events)
    finally:
        browser.close()
    size_mb = os.path.getsize(args.page) / 1e6
    fraction = drawn_fraction(png, region)
    print(f"{args.page}: {size_mb:.1f} MB, first render {render_s:.2f} s, "
          f"{100 * fraction:.1f}% of the region drawn, screenshot {args.screenshot}")
    failed = False
    for e in errors:
        print(f"  console error: {e}")
        failed = True
    if not rendered:
        print(f"  not rendered after {render_s:.1f} s (plotly's newPlot did not resolve)")
        failed = True
    if fraction < args.min_fraction:
        print(f"  nothing drawn: {100 * fraction:.2f}% < {100 * args.min_fraction:.2f}% "
              f"non-background pixels in region {args.region}")
        failed = True
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
