#!/usr/bin/env python3
"""What watching a run costs (BENCHMARKS.md, "Live view"): the same tracked run without and with
`--view`, alternating, ROUNDS times each. With --view a client polls the page's data as the page
does (status and new frames every 0.5 s, the current picture when it changed), so the server's
work is counted too. Prints a Markdown table of median processing fps and the frame loop's own
time on the view (the run's report).

usage: bench/view_cost.py [--hivox build/hivox] [--data ../shared/data/tum_fr1_rpy]
                          [--frames 300] [--rounds 3] [--view-fps 4]
"""
import argparse
import json
import re
import statistics
import subprocess
import tempfile
import threading
import time
import urllib.request
from pathlib import Path


def poll(url, stop, counts):
    frames, version = 0, -1
    while not stop.is_set():
        try:
            status = json.load(urllib.request.urlopen(url + "api/status.json", timeout=5))
            more = json.load(urllib.request.urlopen(f"{url}api/frames.json?from={frames}", timeout=5))
            frames += len(more["frames"])
            if status["render_version"] != version:
                version = status["render_version"]
                for kind in ("shaded", "depth"):
                    urllib.request.urlopen(f"{url}api/render/{kind}.png?v={version}", timeout=5).read()
                counts["images"] += 2
            counts["polls"] += 1
        except OSError:
            pass
        time.sleep(0.5)


def one_run(args, view, out):
    cmd = [args.hivox, "reconstruct", args.data, "--frames", str(args.frames), "--out", out,
           "--overwrite"]
    if view:
        cmd += ["--view", "--view-fps", str(args.view_fps)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    stop, counts, lines, client = threading.Event(), {"polls": 0, "images": 0}, [], None
    for line in proc.stdout:
        lines.append(line)
        m = re.search(r"live view: (http://\S+/)", line)
        if m and client is None:
            client = threading.Thread(target=poll, args=(m.group(1), stop, counts))
            client.start()
    proc.wait()
    stop.set()
    if client:
        client.join()
    stats = json.load(open(Path(out) / "stats.json"))
    text = "".join(lines)
    loop = re.search(r"live view: (\d+) renders, ([\d.]+) s of the frame loop", text)
    return stats["fps"], stats.get("ate_rmse_m"), loop, counts


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--hivox", default="build/hivox")
    p.add_argument("--data", default="../shared/data/tum_fr1_rpy")
    p.add_argument("--frames", type=int, default=300)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--view-fps", type=float, default=4)
    args = p.parse_args()
    fps = {False: [], True: []}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            for view in (False, True):
                f, ate, loop, counts = one_run(args, view, str(Path(tmp) / "out"))
                fps[view].append(f)
                extra = (f", {loop.group(1)} renders, {loop.group(2)} s in the loop, "
                         f"{counts['polls']} polls, {counts['images']} images") if loop else ""
                print(f"round {r + 1} {'--view' if view else 'plain '}: {f:.2f} fps, ATE {ate}{extra}",
                      flush=True)
    a, b = statistics.median(fps[False]), statistics.median(fps[True])
    print(f"\n| run | processing fps (median of {args.rounds}) |\n| --- | ---: |")
    print(f"| without --view | {a:.2f} |\n| with --view ({args.view_fps:g} renders/s, a client polling) | {b:.2f} |")
    print(f"\ncost: {100 * (1 - b / a):.1f} % of the frame rate")


if __name__ == "__main__":
    main()
