"""Memory bandwidth, stream-like, with numpy: copy (a = b) and add (a = b + c) on float32 arrays
far larger than the caches, 1 and 2 threads (numpy releases the GIL in these loops; each thread
works on its own arrays). Bytes counted as the kernel's reads + writes (no write-allocate).

Prints ``RESULT {json}`` with GB/s (1e9 B/s), best of several repeats.
"""

from __future__ import annotations

import json
import threading
import time

import numpy as np

MB = 1 << 20


def _run(threads: int, kind: str, nbytes: int, repeats: int) -> float:
    n = nbytes // 4
    arrays = [
        (np.ones(n, np.float32), np.ones(n, np.float32), np.ones(n, np.float32))
        for _ in range(threads)
    ]

    def work(a, b, c):
        if kind == "copy":
            np.copyto(a, b)
        else:
            np.add(b, c, out=a)

    streams = 2 if kind == "copy" else 3
    best = float("inf")
    for _ in range(repeats):
        ts = [threading.Thread(target=work, args=arr) for arr in arrays]
        t0 = time.perf_counter()
        for t in ts:
            t.start()
        for t in ts:
            t.join()
        best = min(best, time.perf_counter() - t0)
    return threads * streams * nbytes / best / 1e9


def main() -> None:
    out = {}
    for threads in (1, 2):
        for kind in ("copy", "add"):
            out[f"{kind}_{threads}t_gbs"] = _run(threads, kind, 256 * MB, 8)
    print("RESULT " + json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
