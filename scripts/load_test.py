#!/usr/bin/env python3
"""Load on one server while a worker runs: uploaders and status pollers at once (issue 12).

Starts a reconduit-server on a free port with a fresh data folder (connection caps raised so
that every simulated client is admitted: they all come from 127.0.0.1; uploads keep the
server's default limits, so most are answered 429 or 503 with Retry-After) and a reconduit-worker
on the same folder, uploads one small job whose status is polled, then runs two `wrk`
processes (Debian package `wrk`) for --seconds: --uploaders connections each POSTing a zip of
--photos photos again and again, and --pollers connections each GETting that job's status
again and again (closed loop: the next request as soon as the answer is in). 429 and 503 with
Retry-After are correct answers of a full server; any other 5xx, a 429/503 without
Retry-After, or a socket error counts as a failure. Prints requests per second, latency
percentiles and answers by status for each group, then checks that the service is whole
afterwards: /healthz answers, every accepted upload is a job, the polled job is untouched.
Exits 1 on any failure.

  python3 scripts/load_test.py                      # 100 uploaders, 1000 pollers, 30 s
  python3 scripts/load_test.py --uploaders 10 --pollers 100 --seconds 10
"""
import argparse
import http.client
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time

from upload_latency import ROOT, DEFAULT_PHOTOS, build_zip, free_port, stop, wait_until_up

LUA = os.path.join(ROOT, "scripts", "load", "count.lua")


# The result of a group with no clients.
EMPTY = {"requests": 0, "seconds": 1.0, "statuses": {}, "missing_retry_after": 0,
         "socket_errors": {}, "latency_ms": {"p50": 0.0, "p90": 0.0, "p99": 0.0, "max": 0.0}}


def get_json(port, path):
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
    connection.request("GET", path)
    response = connection.getresponse()
    return response.status, json.loads(response.read() or b"null")


def wrk(port, path, connections, seconds, body=None):
    """Starts wrk against path; with body (a file), POSTs it as application/zip."""
    command = ["wrk", "-t", "2", "-c", str(connections), "-d", "%ds" % seconds,
               "--timeout", "30s", "-s", LUA, "http://127.0.0.1:%d%s" % (port, path)]
    if body is not None:
        command += ["--", body, "application/zip"]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def parse(output):
    for line in output.splitlines():
        if line.startswith("LOAD_RESULT "):
            return json.loads(line[len("LOAD_RESULT "):])
    sys.exit("wrk printed no result:\n" + output)


def failures_of(result):
    bad = sum(count for status, count in result["statuses"].items()
              if int(status) >= 500 and int(status) != 503)
    bad += result["missing_retry_after"]
    bad += sum(result["socket_errors"].values())
    return bad


def report(name, result):
    statuses = ", ".join("%s: %d" % item for item in sorted(result["statuses"].items()))
    latency = result["latency_ms"]
    print("%-10s %7d requests, %8.1f req/s; latency p50 %7.1f ms, p90 %7.1f ms, p99 %7.1f ms, "
          "max %7.1f ms" % (name, result["requests"], result["requests"] / result["seconds"],
                            latency["p50"], latency["p90"], latency["p99"], latency["max"]))
    print("%-10s answers: %s; socket errors: %s; 429/503 without Retry-After: %d" %
          ("", statuses or "none", result["socket_errors"], result["missing_retry_after"]))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--server", default=os.path.join(ROOT, "build/ci/server/reconduit-server"))
    parser.add_argument("--worker", default=os.path.join(ROOT, "build/ci/worker/reconduit-worker"),
                        help="the worker to run meanwhile ('' for none)")
    parser.add_argument("--uploaders", type=int, default=100)
    parser.add_argument("--pollers", type=int, default=1000)
    parser.add_argument("--seconds", type=int, default=30)
    parser.add_argument("--photos", type=int, default=3, help="photos per uploaded zip")
    parser.add_argument("--photos-dir", default=DEFAULT_PHOTOS)
    parser.add_argument("--server-arg", action="append", default=[],
                        help="extra flag for the server, e.g. --server-arg=--upload-threads=4")
    args = parser.parse_args()
    if shutil.which("wrk") is None:
        sys.exit("load_test: wrk is not installed (apt-get install wrk)")
    # Each connection is a descriptor in wrk and in the server.
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    wanted = 4 * (args.uploaders + args.pollers) + 1024
    if soft < wanted:
        resource.setrlimit(resource.RLIMIT_NOFILE, (min(wanted, hard), hard))

    work = tempfile.mkdtemp(prefix="load_test_")
    server = worker = None
    failed = False
    try:
        data = os.path.join(work, "data")
        upload_zip = os.path.join(work, "upload.zip")
        build_zip(upload_zip, args.photos_dir, args.photos)
        port = free_port()
        # Room for every client twice over: a refused upload's connection is closed after its
        # answer (its body unread) and lingers up to 2 s while wrk opens the next one.
        clients = 2 * (args.uploaders + args.pollers) + 64
        server_log = open(os.path.join(work, "server.log"), "w")
        server = subprocess.Popen(
            [args.server, "--port", str(port), "--data", data, "--max-connections", str(clients),
             "--max-connections-per-address", str(clients)] + args.server_arg,
            stdout=server_log, stderr=subprocess.STDOUT)
        if not wait_until_up(port, time.monotonic() + 20):
            sys.exit("the server did not start; see " + server_log.name)
        created = subprocess.run(
            ["curl", "-s", "-H", "Content-Type: application/zip", "--data-binary",
             "@" + upload_zip, "http://127.0.0.1:%d/api/v1/jobs" % port],
            capture_output=True, text=True, check=True).stdout
        job_id = json.loads(created)["id"]
        status_path = "/api/v1/jobs/" + job_id
        if args.worker:
            worker_log = open(os.path.join(work, "worker.log"), "w")
            worker = subprocess.Popen([args.worker, "--data", data, "--poll", "0.2"],
                                      stdout=worker_log, stderr=subprocess.STDOUT)

        print("load: %d uploaders (%d photos, %.1f MB a zip) and %d pollers of one job's status "
              "for %d s, %s" % (args.uploaders, args.photos, os.path.getsize(upload_zip) / 1e6,
                                args.pollers, args.seconds,
                                "a worker running" if worker else "no worker"))
        groups = [("uploads", wrk(port, "/api/v1/jobs", args.uploaders, args.seconds,
                                  body=upload_zip) if args.uploaders > 0 else None),
                  ("status", wrk(port, status_path, args.pollers, args.seconds)
                   if args.pollers > 0 else None)]
        results = {}
        for name, process in groups:
            results[name] = parse(process.communicate()[0]) if process else EMPTY
            report(name, results[name])
        upload_result, poll_result = results["uploads"], results["status"]
        print("load average at the end: %.2f %.2f %.2f" % os.getloadavg())

        # Whole afterwards: alive, every accepted upload a job (an upload wrk gave up on at the
        # end may still have been accepted: at least as many jobs), the polled job readable.
        code, _ = get_json(port, "/healthz")
        _, listing = get_json(port, "/api/v1/jobs?limit=1")
        accepted = upload_result["statuses"].get("201", 0)
        code_job, job = get_json(port, status_path)
        print("after: /healthz %d; %d jobs for 1 + %d accepted uploads; polled job %d, %s" %
              (code, listing["total"], accepted, code_job, job.get("state")))
        bad = failures_of(upload_result) + failures_of(poll_result)
        if bad or code != 200 or code_job != 200 or listing["total"] < 1 + accepted:
            print("load: FAILED (%d failed answers)" % bad)
            failed = True
        else:
            print("load: passed (no failed answer)")
    finally:
        stop(worker, server)
        shutil.rmtree(work, ignore_errors=True)
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
