-- wrk script for scripts/load_test.py: counts the answers by status, checks that every 429 and
-- 503 carries Retry-After, and prints one machine-readable line at the end:
--   LOAD_RESULT {"requests": N, "statuses": {...}, "missing_retry_after": N, "latency_ms": {...}}
-- With an argument (`wrk ... -s count.lua URL -- FILE CONTENT_TYPE`) every request is a POST of
-- FILE's bytes with that Content-Type (the uploaders); without, a GET (the pollers).
local threads = {}

function setup(thread)
  table.insert(threads, thread)
end

function init(args)
  statuses = {}
  missing_retry_after = 0
  if args[1] ~= nil then
    local file = assert(io.open(args[1], "rb"))
    wrk.method = "POST"
    wrk.body = file:read("*a")
    file:close()
    wrk.headers["Content-Type"] = args[2] or "application/zip"
  end
  -- wrk formats the request after this returns (wrk.init calls init, then wrk.format).
end

function response(status, headers, body)
  local key = tostring(status)
  statuses[key] = (statuses[key] or 0) + 1
  if (status == 429 or status == 503) and headers["Retry-After"] == nil then
    missing_retry_after = missing_retry_after + 1
  end
end

function done(summary, latency, requests)
  local total = {}
  local missing = 0
  for _, thread in ipairs(threads) do
    for key, count in pairs(thread:get("statuses")) do
      total[key] = (total[key] or 0) + count
    end
    missing = missing + thread:get("missing_retry_after")
  end
  local parts = {}
  for key, count in pairs(total) do
    table.insert(parts, string.format('"%s": %d', key, count))
  end
  local errors = summary.errors
  io.write(string.format(
    'LOAD_RESULT {"requests": %d, "seconds": %.3f, "statuses": {%s}, "missing_retry_after": %d, ' ..
    '"socket_errors": {"connect": %d, "read": %d, "write": %d, "timeout": %d}, ' ..
    '"latency_ms": {"p50": %.2f, "p90": %.2f, "p99": %.2f, "max": %.2f}}\n',
    summary.requests, summary.duration / 1e6, table.concat(parts, ", "), missing,
    errors.connect, errors.read, errors.write, errors.timeout,
    latency:percentile(50) / 1000, latency:percentile(90) / 1000, latency:percentile(99) / 1000,
    latency.max / 1000))
end
