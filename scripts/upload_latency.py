#!/usr/bin/env python3
"""Latency of /healthz and a job's status while large zip uploads are admitted (issue 12).

Starts a reconduit-server on a free port with a fresh data folder, uploads one small job (its
status is polled), then sends N concurrent zip uploads of PHOTOS photos each (the kermit photos
repeated, stored uncompressed: about 170 MB for 1000) with curl while a poller requests
/healthz and GET /api/v1/jobs/{id} every 50 ms. Prints the latency percentiles of each, measured
from the start of the first upload to the end of the last, and the uploads' status codes.

  python3 scripts/upload_latency.py --server build/ci/server/reconduit-server --uploads 2

With --worker (as scripts/start.sh runs the service) a reconduit-worker on the same data folder
runs the small job (the whole pipeline on 3 photos) and then the uploaded ones while the
uploads arrive, so the server competes with a busy worker for the two cores. A measurement,
not a test: run it on a quiet machine and read the figures.

  python3 scripts/upload_latency.py --uploads 8 --worker build/ci/worker/reconduit-worker
"""
import argparse
import http.client
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
import zipfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_PHOTOS = os.path.join(ROOT, "..", "shared", "datasets", "kermit", "images")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def build_zip(path, photos_dir, count):
    names = sorted(n for n in os.listdir(photos_dir) if n.lower().endswith(".jpg"))
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED) as archive:
        for i in range(count):
            source = names[i % len(names)]
            archive.write(os.path.join(photos_dir, source), "photo_%04d_%s" % (i, source))


def percentile(values, p):
    if not values:
        return float("nan")
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(p / 100.0 * (len(ordered) - 1))))]


def poll(port, path, stop, samples, failures):
    while not stop.is_set():
        start = time.monotonic()
        try:
            connection = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
            connection.request("GET", path)
            response = connection.getresponse()
            response.read()
            connection.close()
            if response.status != 200:
                failures.append(response.status)
        except OSError as error:
            failures.append(str(error))
        elapsed = (time.monotonic() - start) * 1000.0
        samples.append(elapsed)
        time.sleep(max(0.0, 0.05 - elapsed / 1000.0))


def stop(*processes):
    """Asks each started process (None: never started) to end, and waits for it."""
    for process in processes:
        if process is not None:
            process.terminate()
            process.wait(timeout=60)


def wait_until_up(port, deadline):
    while time.monotonic() < deadline:
        try:
            connection = http.client.HTTPConnection("127.0.0.1", port, timeout=1)
            connection.request("GET", "/healthz")
            if connection.getresponse().status == 200:
                return True
        except OSError:
            time.sleep(0.05)
    return False


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--server", default=os.path.join(ROOT, "build/ci/server/reconduit-server"))
    parser.add_argument("--uploads", type=int, default=2)
    parser.add_argument("--photos", type=int, default=1000)
    parser.add_argument("--photos-dir", default=DEFAULT_PHOTOS)
    parser.add_argument("--worker", default="",
                        help="a reconduit-worker to run on the same data folder meanwhile")
    parser.add_argument("--server-arg", action="append", default=[],
                        help="extra flag for the server, e.g. --server-arg=--upload-threads=2")
    args = parser.parse_args()

    work = tempfile.mkdtemp(prefix="upload_latency_")
    server = None
    worker = None
    try:
        zip_path = os.path.join(work, "photos.zip")
        build_zip(zip_path, args.photos_dir, args.photos)
        small_zip = os.path.join(work, "small.zip")
        build_zip(small_zip, args.photos_dir, 3)
        port = free_port()
        log = open(os.path.join(work, "server.log"), "w")
        server = subprocess.Popen(
            [args.server, "--port", str(port), "--data", os.path.join(work, "data"),
             "--max-concurrent-uploads", str(max(8, args.uploads))] + args.server_arg,
            stdout=log, stderr=subprocess.STDOUT)
        if not wait_until_up(port, time.monotonic() + 20):
            sys.exit("the server did not start; see " + log.name)
        created = subprocess.run(
            ["curl", "-s", "-o", "/dev/null", "-D", "-", "-H", "Content-Type: application/zip",
             "--data-binary", "@" + small_zip, "http://127.0.0.1:%d/api/v1/jobs" % port],
            capture_output=True, text=True, check=True).stdout
        location = [line.split(":", 1)[1].strip() for line in created.splitlines()
                    if line.lower().startswith("location:")][0]
        if args.worker:
            worker_log = open(os.path.join(work, "worker.log"), "w")
            worker = subprocess.Popen(
                [args.worker, "--data", os.path.join(work, "data"), "--poll", "0.2"],
                stdout=worker_log, stderr=subprocess.STDOUT)
            # The uploads start once the worker is busy with the small job.
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline:
                connection = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
                connection.request("GET", location)
                if b'"running"' in connection.getresponse().read():
                    break
                time.sleep(0.1)

        stop = threading.Event()
        results = {"/healthz": ([], []), location: ([], [])}
        pollers = [threading.Thread(target=poll, args=(port, path, stop, s, f))
                   for path, (s, f) in results.items()]
        uploads = [subprocess.Popen(
            ["curl", "-s", "-o", "/dev/null", "-w", "%{http_code} %{time_total}",
             "-H", "Content-Type: application/zip", "--data-binary", "@" + zip_path,
             "http://127.0.0.1:%d/api/v1/jobs" % port],
            stdout=subprocess.PIPE, text=True) for _ in range(args.uploads)]
        for thread in pollers:
            thread.start()
        outcomes = [upload.communicate()[0] for upload in uploads]
        stop.set()
        for thread in pollers:
            thread.join()

        size_mb = os.path.getsize(zip_path) / 1e6
        print("%d concurrent uploads of %d photos (%.0f MB each), %s: status and seconds: %s" %
              (args.uploads, args.photos, size_mb,
               "a worker running" if worker is not None else "no worker", ", ".join(outcomes)))
        print("load average at the end: %.2f %.2f %.2f" % os.getloadavg())
        if worker is not None:
            connection = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
            connection.request("GET", location)
            status = json.loads(connection.getresponse().read())
            print("the worker's first job at the end: %s, stage %s" %
                  (status.get("state"), status.get("stage")))
        for path, (samples, failures) in results.items():
            name = "/healthz" if path == "/healthz" else "GET /api/v1/jobs/{id}"
            print("%-22s n=%4d p50 %7.1f ms  p99 %7.1f ms  max %7.1f ms  failures %d" %
                  (name, len(samples), percentile(samples, 50), percentile(samples, 99),
                   max(samples) if samples else float("nan"), len(failures)))
    finally:
        stop(worker, server)
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
