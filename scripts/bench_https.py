"""Latency of GET /api/status under concurrent clients, over HTTP or HTTPS (issue 35's target:
the HTTPS p99 within 2x of plain HTTP's with 50 clients).

Each client thread keeps one connection (keep-alive, as a browser does) and sends requests
back to back for the given seconds; the TLS handshake is timed apart. Prints one JSON line.
Usage: bench_https.py URL [--cacert PEM] [--clients 50] [--seconds 10]"""
import argparse
import http.client
import json
import ssl
import statistics
import threading
import time
import urllib.parse

ap = argparse.ArgumentParser()
ap.add_argument("url")
ap.add_argument("--cacert")
ap.add_argument("--clients", type=int, default=50)
ap.add_argument("--seconds", type=float, default=10.0)
a = ap.parse_args()
u = urllib.parse.urlsplit(a.url)
ctx = ssl.create_default_context(cafile=a.cacert) if u.scheme == "https" else None

lat, connect, errors = [], [], []
lock = threading.Lock()
start = threading.Barrier(a.clients + 1)


def client():
    mine, errs = [], 0
    t0 = time.perf_counter()
    if ctx:
        c = http.client.HTTPSConnection(u.hostname, u.port, context=ctx, timeout=30)
    else:
        c = http.client.HTTPConnection(u.hostname, u.port, timeout=30)
    c.connect()
    hs = time.perf_counter() - t0
    start.wait()
    end = time.perf_counter() + a.seconds
    while time.perf_counter() < end:
        t = time.perf_counter()
        try:
            c.request("GET", u.path or "/")
            r = c.getresponse()
            r.read()
            if r.status != 200:
                errs += 1
        except Exception:
            errs += 1
            c.close()
            c.connect()
            continue
        mine.append(time.perf_counter() - t)
    with lock:
        lat.extend(mine)
        connect.append(hs)
        errors.append(errs)


threads = [threading.Thread(target=client) for _ in range(a.clients)]
for t in threads:
    t.start()
start.wait()
for t in threads:
    t.join()
lat.sort()
q = lambda p: lat[min(len(lat) - 1, int(p * len(lat)))] * 1e3
print(
    json.dumps(
        {
            "scheme": u.scheme,
            "clients": a.clients,
            "requests": len(lat),
            "errors": sum(errors),
            "rps": round(len(lat) / a.seconds, 1),
            "p50_ms": round(q(0.50), 2),
            "p99_ms": round(q(0.99), 2),
            "max_ms": round(lat[-1] * 1e3, 2),
            "connect_median_ms": round(statistics.median(connect) * 1e3, 2),
        }
    )
)
