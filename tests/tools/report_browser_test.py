#!/usr/bin/env python3
"""`skintune report` in a real browser: the page loads in headless Chromium
without a console error, holds every section and chart, and every chart has a
rendered size; a full-page screenshot (1280 px wide) is saved for people.

Chromium is driven over the DevTools protocol on a pipe (--remote-debugging-pipe:
no port, no network). Console errors are what the page itself reports:
Runtime.consoleAPICalled of type error/assert, Runtime.exceptionThrown (an
uncaught exception) and Log.entryAdded of level error (a resource that failed
to load, e.g. an external reference on this offline machine). Chromium's own
stderr noise (dbus, GPU, ...) is never read. The charts are measured with
Runtime.evaluate from outside the page, so the report itself stays script-free.

The same checking code then runs on negative controls made from the report (a
console.error, an uncaught exception, a resource that fails to load, a chart id
removed, a chart rendered at zero size): each must be reported as a failure, so
a checker that sees nothing fails the test.

usage: report_browser_test.py --skintune BIN --fixture RESULT.json [--fixture ...]
                              --work DIR --screenshot PNG [--chromium PATH] [--timeout S]
"""

import argparse
import base64
import json
import os
import select
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time

SECTIONS = ["fig1", "table1-opencl-vs-cuda", "table1-opencl-vs-glsl", "gbps", "axes", "devices"]
WIDTH = 1280


class Timeout(Exception):
    pass


class Deadline:
    def __init__(self, seconds):
        self.end = time.monotonic() + seconds

    def left(self):
        left = self.end - time.monotonic()
        if left <= 0:
            raise Timeout("the test ran out of time")
        return left


def expected_chart_ids(fixtures):
    """The chart ids the report of these inputs must have: fig1-<result>,
    gbps-<device> for every device, axes-<n> for every device x language with a
    status-ok measurement (in the order of the devices)."""
    ids, devices, axes = [], 0, 0
    for index, path in enumerate(fixtures):
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
        tuning = doc["tuning"] if doc.get("kind") == "skintune-paper-result" else doc
        ids.append("fig1-%d" % index)
        for device in tuning["devices"]:
            langs = {m["variant"]["lang"] for m in tuning["measurements"]
                     if m["device_id"] == device["id"] and m["status"] == "ok"}
            devices += 1
            axes += len(langs)
    ids += ["gbps-%d" % i for i in range(devices)]
    ids += ["axes-%d" % i for i in range(axes)]
    return ids


class Browser:
    """Headless Chromium on a DevTools pipe (fd 3: commands in, fd 4: replies out)."""

    def __init__(self, chromium, deadline):
        self.deadline = deadline
        self.profile = tempfile.mkdtemp(prefix="skintune-report-chromium-")  # fresh every run
        to_chrome_r, self.to_chrome = os.pipe()
        self.from_chrome, from_chrome_w = os.pipe()

        def child():
            os.dup2(to_chrome_r, 3)
            os.dup2(from_chrome_w, 4)

        self.process = subprocess.Popen(
            [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--user-data-dir=" + self.profile,
             "--remote-debugging-pipe", "--no-first-run", "--no-default-browser-check", "--disable-extensions",
             "--hide-scrollbars", "about:blank"],
            pass_fds=(3, 4), preexec_fn=child, start_new_session=True,
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self.buffer = b""
        self.next_id = 0
        self.events = []

    def close(self):
        try:
            if self.process.poll() is None:
                try:
                    self.call("Browser.close", timeout=5)
                    self.process.wait(timeout=5)
                except Exception:
                    pass
        finally:
            if self.process.poll() is None:
                os.killpg(self.process.pid, signal.SIGKILL)  # its own session: chromium and its children
                self.process.wait()
            for fd in (self.to_chrome, self.from_chrome):
                try:
                    os.close(fd)
                except OSError:
                    pass
            shutil.rmtree(self.profile, ignore_errors=True)

    def _receive(self, until, timeout=None):
        end = time.monotonic() + (timeout if timeout is not None else self.deadline.left())
        while True:
            while b"\0" in self.buffer:
                raw, self.buffer = self.buffer.split(b"\0", 1)
                message = json.loads(raw)
                if until(message):
                    return message
                self.events.append(message)
            left = min(end - time.monotonic(), self.deadline.left())
            if left <= 0:
                raise Timeout("no reply from chromium")
            ready, _, _ = select.select([self.from_chrome], [], [], left)
            if ready:
                data = os.read(self.from_chrome, 1 << 20)
                if not data:
                    raise RuntimeError("chromium closed the DevTools pipe (exit %s)" % self.process.poll())
                self.buffer += data

    def send(self, method, params=None, session=None):
        self.next_id += 1
        message = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = session
        os.write(self.to_chrome, json.dumps(message).encode() + b"\0")
        return self.next_id

    def call(self, method, params=None, session=None, timeout=None):
        ident = self.send(method, params, session)
        reply = self._receive(lambda m: m.get("id") == ident, timeout)
        if "error" in reply:
            raise RuntimeError("%s: %s" % (method, reply["error"]))
        return reply["result"]

    def drain(self, seconds):
        """Collects the events that arrive within `seconds`."""
        try:
            self._receive(lambda m: False, seconds)
        except Timeout:
            self.deadline.left()  # re-raises when the whole test is out of time

    def check_page(self, path, expected_ids, screenshot=None):
        """Loads `path` at 1280 px and returns (problems, facts)."""
        target = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        self.events = []
        for domain in ("Runtime.enable", "Log.enable", "Page.enable"):
            self.call(domain, session=session)
        self.call("Emulation.setDeviceMetricsOverride",
                  {"width": WIDTH, "height": 900, "deviceScaleFactor": 1, "mobile": False}, session=session)
        navigation = self.call("Page.navigate", {"url": "file://" + os.path.abspath(path)}, session=session)
        problems = []
        if navigation.get("errorText"):
            problems.append("navigation failed: " + navigation["errorText"])
        else:
            self._receive(lambda m: m.get("method") == "Page.loadEventFired" and m.get("sessionId") == session)
        self.drain(0.3)  # late console messages and failed loads
        facts = self.evaluate(session, """(() => {
            const ids = %s.concat(%s);
            const rect = e => { const r = e.getBoundingClientRect(); return [r.width, r.height]; };
            return JSON.stringify({
              readyState: document.readyState,
              title: document.title,
              missing: ids.filter(id => !document.getElementById(id)),
              notSvgChart: ids.filter(id => /^(fig1|gbps|axes)-/.test(id) && document.getElementById(id) &&
                                   !document.getElementById(id).matches('svg.chart')),
              charts: [...document.querySelectorAll('svg.chart')].map(e => ({id: e.id, size: rect(e)})),
              scripts: document.scripts.length,
              height: document.documentElement.scrollHeight,
              width: document.documentElement.scrollWidth
            });
        })()""" % (json.dumps(SECTIONS), json.dumps(expected_ids)))
        for event in self.events:
            if event.get("sessionId") != session:
                continue
            method, params = event.get("method"), event.get("params", {})
            if method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
                text = " ".join(str(a.get("value", a.get("description", ""))) for a in params.get("args", []))
                problems.append("console %s: %s" % (params["type"], text))
            elif method == "Runtime.exceptionThrown":
                details = params.get("exceptionDetails", {})
                problems.append("uncaught exception: %s" % details.get("exception", {}).get(
                    "description", details.get("text", "")))
            elif method == "Log.entryAdded" and params.get("entry", {}).get("level") == "error":
                entry = params["entry"]
                problems.append("console error (%s): %s %s" % (entry.get("source"), entry.get("text"),
                                                              entry.get("url", "")))
        if facts["readyState"] != "complete" or not facts["title"]:
            problems.append("page did not load (readyState %s, title %r)" % (facts["readyState"], facts["title"]))
        for ident in facts["missing"]:
            problems.append("missing id: " + ident)
        for ident in facts["notSvgChart"]:
            problems.append("not an svg.chart: " + ident)
        for chart in facts["charts"]:
            if not (chart["size"][0] > 0 and chart["size"][1] > 0):
                problems.append("chart %s has rendered size %gx%g" % (chart["id"] or "(no id)", *chart["size"]))
        chart_ids = [c["id"] for c in facts["charts"]]
        for ident in expected_ids:
            if ident not in chart_ids and ident not in facts["missing"]:
                problems.append("chart %s is not an svg.chart" % ident)
        if screenshot:
            height = max(int(facts["height"]), 1)
            shot = self.call("Page.captureScreenshot",
                             {"format": "png", "captureBeyondViewport": True,
                              "clip": {"x": 0, "y": 0, "width": WIDTH, "height": height, "scale": 1}},
                             session=session)
            with open(screenshot, "wb") as f:
                f.write(base64.b64decode(shot["data"]))
        self.call("Target.closeTarget", {"targetId": target})
        return problems, facts

    def evaluate(self, session, expression):
        result = self.call("Runtime.evaluate", {"expression": expression, "returnByValue": True}, session=session)
        if "exceptionDetails" in result:
            raise RuntimeError("the checking expression failed: %s" % result["exceptionDetails"])
        return json.loads(result["result"]["value"])


def png_size(path):
    with open(path, "rb") as f:
        head = f.read(24)
    if head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        return None
    return struct.unpack(">II", head[16:24])


def static_problems(html):
    """The report's own promises, on the file as written."""
    problems = []
    for bad in ("<script", "http:", "https:", "//", "@import", "<link", "url(", "src="):
        if bad in html:
            problems.append("the report contains %r" % bad)
    return problems


def negative_controls(html, work, chart_ids):
    """Pages that must fail the check, with what the failure must mention."""
    def page(name, text):
        path = os.path.join(work, "negative-%s.html" % name)
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)
        return path

    gbps = ([i for i in chart_ids if i.startswith("gbps-")] or chart_ids)[-1]
    axes = ([i for i in chart_ids if i.startswith("axes-")] or chart_ids)[0]
    end = "</body>"
    return [
        (page("console-error", html.replace(end, "<script>console.error('deliberate console error')</script>" + end)),
         "console error: deliberate console error"),
        (page("exception", html.replace(end, "<script>throw new Error('deliberate exception')</script>" + end)),
         "uncaught exception: Error: deliberate exception"),
        (page("failed-load", html.replace(end, "<img src=\"missing-image-of-the-negative-control.png\">" + end)),
         "missing-image-of-the-negative-control.png"),
        (page("missing-chart", html.replace('id="%s"' % gbps, 'id="renamed-chart"', 1)),
         "missing id: " + gbps),
        (page("zero-size-chart", html.replace("</style>", "#%s{display:none}</style>" % axes, 1)),
         "chart %s has rendered size 0x0" % axes),
    ]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--skintune", required=True)
    parser.add_argument("--fixture", action="append", required=True)
    parser.add_argument("--work", required=True)
    parser.add_argument("--screenshot", required=True)
    parser.add_argument("--chromium", default=shutil.which("chromium") or "/usr/bin/chromium")
    parser.add_argument("--timeout", type=float, default=60.0)
    args = parser.parse_args()
    deadline = Deadline(args.timeout)

    def terminated(signum, frame):  # ctest's own timeout: still close chromium (finally below)
        raise Timeout("terminated by signal %d" % signum)

    signal.signal(signal.SIGTERM, terminated)
    signal.signal(signal.SIGINT, terminated)

    shutil.rmtree(args.work, ignore_errors=True)
    os.makedirs(args.work)
    os.makedirs(os.path.dirname(os.path.abspath(args.screenshot)), exist_ok=True)
    report = os.path.join(args.work, "report.html")
    markdown = os.path.join(args.work, "report.md")
    try:
        run = subprocess.run([args.skintune, "report", *args.fixture, "-o", report, "--markdown", markdown],
                             capture_output=True, text=True, timeout=deadline.left())
    except subprocess.TimeoutExpired:
        print("FAIL: skintune report did not finish within %gs" % args.timeout)
        return 1
    if run.returncode != 0:
        print("FAIL: skintune report exited %d: %s" % (run.returncode, run.stderr.strip()))
        return 1
    with open(report, encoding="utf-8") as f:
        html = f.read()
    failures = static_problems(html)
    chart_ids = expected_chart_ids(args.fixture)
    if not os.access(args.chromium, os.X_OK):
        print("FAIL: no chromium at %s (scripts/bootstrap installs it)" % args.chromium)
        return 1

    browser = Browser(args.chromium, deadline)
    try:
        if os.path.exists(args.screenshot):
            os.remove(args.screenshot)
        problems, facts = browser.check_page(report, chart_ids, screenshot=args.screenshot)
        failures += ["report: " + p for p in problems]
        if facts["scripts"] != 0:
            failures.append("report: the page has %d script element(s)" % facts["scripts"])
        if facts["width"] > WIDTH:
            failures.append("report: the page is %d px wide at a %d px window (horizontal scrolling)"
                            % (facts["width"], WIDTH))
        print("report: %d chart(s), sizes %s" % (len(facts["charts"]), ", ".join(
            "%s %gx%g" % (c["id"], *c["size"]) for c in facts["charts"])))
        size = png_size(args.screenshot) if os.path.exists(args.screenshot) else None
        if size is None or size[0] != WIDTH or size[1] < 1000:
            failures.append("screenshot %s: not a %d px wide full-page PNG (%s)" % (args.screenshot, WIDTH, size))
        else:
            print("screenshot: %s (%dx%d)" % (args.screenshot, *size))

        for path, expected in negative_controls(html, args.work, chart_ids):
            problems, _ = browser.check_page(path, chart_ids)
            caught = [p for p in problems if expected in p]
            name = os.path.basename(path)
            if caught:
                print("negative control %s: caught as expected (%s)" % (name, caught[0]))
            else:
                failures.append("negative control %s was not caught (wanted %r, got %s)" % (name, expected, problems))
    except Timeout as e:
        failures.append("timeout after %gs: %s" % (args.timeout, e))
    finally:
        browser.close()

    for failure in failures:
        print("FAIL: " + failure)
    if not failures:
        print("PASS: the report loads without console errors and every chart has a rendered size")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
