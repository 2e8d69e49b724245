"""Plays a `render --html` page in headless Chromium for N real seconds over the DevTools pipe
and prints window.tactusStats: animation frames while playing, frames later than 25 ms
(dropped at 60 Hz), the longest gap, the longest and total time inside the page's callbacks,
and the audio clock. Usage: python3 benches/html_play.py PAGE.html SECONDS"""
import json, os, subprocess, sys, time, tempfile
page, secs = os.path.abspath(sys.argv[1]), float(sys.argv[2])
r_in, w_in = os.pipe()    # we write -> chrome fd 3
r_out, w_out = os.pipe()  # chrome fd 4 -> we read
prof = tempfile.mkdtemp()
def fds():
    os.dup2(r_in, 3); os.dup2(w_out, 4)
p = subprocess.Popen(["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--remote-debugging-pipe",
    "--autoplay-policy=no-user-gesture-required", "--user-data-dir=" + prof, "--window-size=1280,800",
    "file://" + page + "#t=0&play"], pass_fds=(3, 4), preexec_fn=fds, stderr=subprocess.DEVNULL)
os.close(r_in); os.close(w_out)
buf = b""; n = 0
def send(method, params=None, session=None):
    global n; n += 1
    m = {"id": n, "method": method, "params": params or {}}
    if session: m["sessionId"] = session
    os.write(w_in, json.dumps(m).encode() + b"\0"); return n
def wait(i):
    global buf
    while True:
        while b"\0" not in buf: buf += os.read(r_out, 1 << 16)
        msg, buf = buf.split(b"\0", 1); m = json.loads(msg)
        if m.get("id") == i: return m
time.sleep(2)
targets = wait(send("Target.getTargets"))["result"]["targetInfos"]
tid = [t for t in targets if t["type"] == "page"][0]["targetId"]
sid = wait(send("Target.attachToTarget", {"targetId": tid, "flatten": True}))["result"]["sessionId"]
expr = "JSON.stringify({stats: window.tactusStats, t: document.getElementById('audio').currentTime, audio: document.getElementById('status').dataset.audio})"
reset = "Object.assign(window.tactusStats, {frames: 0, late: 0, maxGapMs: 0, maxWorkMs: 0, sumWorkMs: 0}), " + expr
start = wait(send("Runtime.evaluate", {"expression": reset, "returnByValue": True}, sid))["result"]["result"]["value"]
time.sleep(secs)
end = wait(send("Runtime.evaluate", {"expression": expr, "returnByValue": True}, sid))["result"]["result"]["value"]
print("start", start); print("end  ", end)
send("Browser.close"); p.wait(timeout=10)
