"""``jeanscv serve`` under load: 300 requests over loopback, 12 at a time.

    python -m bench.serve_load
    python -m bench.serve_load --requests 400 --concurrency 16 --seed 2

A fresh server (its own process on 127.0.0.1, default options but a 20 MB upload cap)
gets a shuffled mix: uploads of good photos (the shared real photos at their own size,
a few upscaled to 12 MP), uploads of bad files (empty, truncated, text, a PNG header
claiming 50000x50000 pixels, a body over the upload cap), clicks on photos uploaded
before, and downloads (image, meme, JSON, SVG, clicks, a few GIFs). A request answered
503 is sent again after the server's Retry-After, as the page does (at most 30 times;
one still refused then counts as a 503).

Prints the answers by status; per request kind the seconds from its first try to its
answer (median, 95th percentile, most), retries included; the server's peak memory
(VmHWM); and the temporary files left while it runs and after Ctrl-C. Passes when every
request is answered with 200 or 4xx, none waits more than 30 s for its answer, the peak
stays under 1.5 GB, no temporary file is left and the server stops with status 0 within
2 s.
"""

from __future__ import annotations

import argparse
import collections
import io
import json
import random
import statistics
import struct
import threading
import time
import zlib

import numpy as np
from PIL import Image

from bench.clicks import SHARED, photo_pairs, upscale
from bench.serve_client import Server

MEMORY_LIMIT = 1.5e9
RETRIES = 30
#: Longest a request may take from its first try to its answer.
WAIT_LIMIT = 30.0


def jpeg(pixels: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    Image.fromarray(pixels).save(buffer, "JPEG", quality=90)
    return buffer.getvalue()


def bad_files(good: bytes) -> dict[str, bytes]:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    bomb = (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", 50000, 50000, 8, 2, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(b"\x00" * 64))
        + chunk(b"IEND", b"")
    )
    return {
        "empty.png": b"",
        "truncated.jpg": good[:400],
        "text.jpg": b"not a picture\n" * 30,
        "bomb.png": bomb,
        "fake.nef": b"II*\x00" + b"\x00" * 400,
        "huge.jpg": b"\xff" * (21 << 20),  # over the 20 MB cap: 413
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--requests", type=int, default=300)
    parser.add_argument("--concurrency", type=int, default=12)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    goods = good_photos()
    bads = list(bad_files(goods[-1][1]).items())
    plan = request_plan(args.requests, args.seed)

    server = Server("--max-upload-mb", "20")
    load = Load(server, goods, bads, plan, args.seed)
    wall = load.run(args.concurrency)
    resident, high_water = server.memory()
    running_leftovers = server.leftovers()
    code, stop_seconds = server.stop()
    after = server.leftovers() + ([str(server.tmp)] if any(server.tmp.iterdir()) else [])

    statuses = load.statuses
    answered = sum(v for k, v in statuses.items() if k != "no answer")
    print(f"{len(plan)} requests, {args.concurrency} at a time, in {wall:.1f} s: {answered} answered")
    print(f"503 (busy, retried after the server's Retry-After): {load.busy} times")
    print("final status: " + ", ".join(f"{k}: {v}" for k, v in sorted(statuses.items(), key=lambda kv: str(kv[0]))))
    print("seconds from a request's first try to its answer:")
    for kind, values in sorted(load.seconds.items()):
        ordered = sorted(values)
        p95 = ordered[min(len(ordered) - 1, round(0.95 * (len(ordered) - 1)))]
        print(
            f"  {kind:9s} {len(values):4d}: p50 {statistics.median(values):5.2f}, p95 {p95:5.2f}, max {max(values):5.2f}"
        )
    longest = max(max(values) for values in load.seconds.values())
    print(f"server memory: peak {high_water / 2**20:.0f} MB (VmHWM), {resident / 2**20:.0f} MB at the end")
    print(f"temporary files: {len(running_leftovers)} while running, {len(after)} after Ctrl-C")
    print(f"Ctrl-C: exit status {code} in {stop_seconds:.1f} s")
    for failure in load.failures[:10]:
        print("FAILED", failure)
    server.remove()
    ok = not load.failures and high_water < MEMORY_LIMIT and not running_leftovers and not after and code == 0
    ok = ok and longest <= WAIT_LIMIT and stop_seconds < 2.0 and not statuses.get(503)
    print("PASS" if ok else "FAIL")
    raise SystemExit(0 if ok else 1)


def good_photos() -> list[tuple[str, bytes]]:
    """``(name, JPEG bytes)`` of the good uploads: the shared real photos at their own
    size, the first three upscaled to 12 MP."""
    pairs = photo_pairs([SHARED])
    if not pairs:
        raise SystemExit(f"no photos in {SHARED}")
    goods = []
    for index, (name, photo_path, mask_path) in enumerate(pairs):
        pixels = np.asarray(Image.open(photo_path).convert("RGB"))
        if index < 3:
            reference = np.asarray(Image.open(mask_path).convert("L")) >= 128
            pixels, _ = upscale(pixels, reference, 12.0)
            name += "-12mp"
        goods.append((f"{name}.jpg", jpeg(pixels)))
    return goods


def request_plan(requests: int, seed: int) -> list[str]:
    """The kinds of the ``requests`` requests, shuffled, an upload first (something to
    click on early)."""
    rng = random.Random(seed)
    kinds = ["upload"] * 50 + ["bad"] * 30 + ["click"] * 70 + ["download"] * 50
    plan = [kinds[i % len(kinds)] for i in range(requests)]
    rng.shuffle(plan)
    return ["upload"] + plan[: requests - 1]


class Load:
    """The requests of one run, sent by worker threads, and what they got, under one lock."""

    def __init__(self, server: Server, goods: list, bads: list, plan: list[str], seed: int) -> None:
        self.server, self.goods, self.bads, self.seed = server, goods, bads, seed
        self.queue = list(enumerate(plan))
        self.photos: list[dict] = []  # answers of good uploads (photo id, size, downloads)
        self.lock = threading.Lock()
        self.statuses: collections.Counter = collections.Counter()
        self.seconds: dict[str, list[float]] = collections.defaultdict(list)
        self.failures: list[str] = []
        self.peak = 0
        self.busy = 0  # 503 answers, each followed by a retry
        self.done = threading.Event()

    def watch(self) -> None:
        while not self.done.is_set():
            self.peak = max(self.peak, self.server.memory()[0])
            time.sleep(0.2)

    def one(self, kind: str, chooser: random.Random) -> None:
        """One request, sent again after the server's Retry-After while it answers 503
        (as the page does), at most ``RETRIES`` times; its seconds count from the first try."""
        began = time.perf_counter()
        for _ in range(RETRIES + 1):
            status, kind_sent, retry = self.attempt_one(kind, chooser)
            if status != 503:
                with self.lock:
                    self.seconds[kind_sent.split()[0]].append(time.perf_counter() - began)
                return
            with self.lock:
                self.busy += 1
            time.sleep(retry)
        with self.lock:
            self.statuses[503] += 1  # still busy after every retry
            self.failures.append(f"{kind}: refused {RETRIES + 1} times")

    def attempt_one(self, kind: str, chooser: random.Random) -> tuple[int, str, float]:
        """One try: (status, the kind sent, the Retry-After in seconds)."""
        server = self.server
        with self.lock:
            known = list(self.photos)
        if kind in ("click", "download") and not known:
            kind = "upload"
        if kind == "upload":
            name, data = chooser.choice(self.goods)
            status, headers, body = server.upload(name, data)
            if status == 200:
                answer = json.loads(body)
                with self.lock:
                    self.photos.append(answer)
        elif kind == "bad":
            name, data = chooser.choice(self.bads)
            status, headers, body = server.upload(name, data)
        elif kind == "click":
            answer = chooser.choice(known)
            width, height = answer["width"], answer["height"]
            points = [[round(chooser.uniform(0.3, 0.7) * width, 1), round(chooser.uniform(0.3, 0.7) * height, 1)]]
            status, headers, body = server.render(answer["photo"], [{"positive": points, "negative": []}])
            result = json.loads(body) if status == 200 else {}
            if status == 200 and "nothing" not in result:  # "nothing clear there" has no result
                with self.lock:
                    self.photos.append(result | {"photo": answer["photo"]})
        else:
            answer = chooser.choice(known)
            what = chooser.choice(["image", "meme", "json", "svg", "clicks", "image", "json", "gif"])
            if what == "gif" and chooser.random() < 0.7:
                what = "svg"  # a GIF takes seconds: a few of them
            path = answer["downloads"][what] + ("?top=load&bottom=test" if what == "meme" else "")
            status, headers, body = server.request("GET", path)
            kind = f"download {what}"
        with self.lock:
            if status != 503:
                self.statuses[status] += 1
            if not (status in (200, 503) or 400 <= status < 500):
                self.failures.append(f"{kind}: {status} {body[:200]!r}")
        headers = {key.lower(): value for key, value in headers.items()}
        return status, kind, float(headers.get("retry-after", 2))

    def worker(self, number: int) -> None:
        chooser = random.Random(self.seed * 1000 + number)
        while True:
            with self.lock:
                if not self.queue:
                    return
                _, kind = self.queue.pop(0)
            try:
                self.one(kind, chooser)
            except Exception as exc:  # noqa: BLE001 - a request that got no answer
                with self.lock:
                    self.statuses["no answer"] += 1
                    self.failures.append(f"{kind}: {type(exc).__name__}: {exc}")

    def run(self, concurrency: int) -> float:
        """Send every request, ``concurrency`` at a time; the seconds it took."""
        watcher = threading.Thread(target=self.watch, daemon=True)
        watcher.start()
        began = time.perf_counter()
        threads = [threading.Thread(target=self.worker, args=(n,)) for n in range(concurrency)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        wall = time.perf_counter() - began
        self.done.set()
        watcher.join()
        return wall


if __name__ == "__main__":
    main()
