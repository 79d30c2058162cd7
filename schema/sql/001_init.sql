-- 001_init: jobs, their event log and their photos.
--
-- Applied by server/storage/migrations.cc inside one transaction together with
-- `PRAGMA user_version = 1`; never edit a migration that has shipped, add 002_*.sql instead.
-- All times are Unix epoch milliseconds (INTEGER), UTC. JSON columns hold text checked with
-- json_valid(). See schema/README.md for the meaning of every column and the state machine.

CREATE TABLE jobs (
  -- 128 random bits as 32 lower-case hex digits (unguessable; doubles as the access key).
  id               TEXT    PRIMARY KEY NOT NULL
                           CHECK (length(id) = 32 AND id NOT GLOB '*[^0-9a-f]*'),
  state            TEXT    NOT NULL DEFAULT 'queued'
                           CHECK (state IN ('queued', 'running', 'succeeded', 'failed', 'canceled')),
  options          TEXT    NOT NULL DEFAULT '{}' CHECK (json_valid(options)),
  created_at       INTEGER NOT NULL,
  -- When the job last entered the queue (creation or restart): the claim order.
  queued_at        INTEGER NOT NULL,
  -- Start of the latest attempt; finish of the latest run.
  started_at       INTEGER,
  finished_at      INTEGER,
  updated_at       INTEGER NOT NULL,
  -- Stage being run (or last run) and overall progress in [0, 1].
  stage            TEXT,
  progress         REAL    NOT NULL DEFAULT 0 CHECK (progress >= 0 AND progress <= 1),
  -- {"<stage>": {"progress": 0.4, "seconds": 12.5, ...}, ...}; merged with json_patch().
  stage_progress   TEXT    NOT NULL DEFAULT '{}' CHECK (json_valid(stage_progress)),
  -- ["ingest", "features", ...]: stages whose output is complete on disk (resume points).
  finished_stages  TEXT    NOT NULL DEFAULT '[]' CHECK (json_valid(finished_stages)),
  -- Runs lost to an expired lease; at max_attempts the job fails instead of being requeued.
  attempts         INTEGER NOT NULL DEFAULT 0 CHECK (attempts >= 0),
  max_attempts     INTEGER NOT NULL DEFAULT 3 CHECK (max_attempts >= 1),
  lease_owner      TEXT,
  lease_until      INTEGER,
  cancel_requested INTEGER NOT NULL DEFAULT 0 CHECK (cancel_requested IN (0, 1)),
  error            TEXT,
  error_stage      TEXT,
  -- Accepted photos (rejected ones are listed in `images` with their reason).
  image_count      INTEGER NOT NULL DEFAULT 0 CHECK (image_count >= 0),
  -- {"registered": 48, "points": 21034, "faces": 100000, ...}
  counts           TEXT    NOT NULL DEFAULT '{}' CHECK (json_valid(counts)),
  result_bytes     INTEGER CHECK (result_bytes IS NULL OR result_bytes >= 0),
  result_sha256    TEXT    CHECK (result_sha256 IS NULL OR
                                  (length(result_sha256) = 64 AND
                                   result_sha256 NOT GLOB '*[^0-9a-f]*')),
  -- A running job always has a lease; no other state has one.
  CHECK ((state = 'running') = (lease_owner IS NOT NULL AND lease_until IS NOT NULL))
);

-- Claim: the oldest queued job.
CREATE INDEX jobs_queued ON jobs (queued_at) WHERE state = 'queued';
-- Lease sweep: running jobs whose lease ran out.
CREATE INDEX jobs_running_lease ON jobs (lease_until) WHERE state = 'running';
-- Listing, newest first, and counts by state.
CREATE INDEX jobs_created ON jobs (created_at);
CREATE INDEX jobs_state ON jobs (state);

CREATE TABLE job_events (
  -- Monotonic across the whole table: clients page with ?after=<last id seen>.
  id       INTEGER PRIMARY KEY AUTOINCREMENT,
  job_id   TEXT    NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
  time     INTEGER NOT NULL,
  stage    TEXT,
  level    TEXT    NOT NULL DEFAULT 'info'
                   CHECK (level IN ('debug', 'info', 'warning', 'error')),
  message  TEXT    NOT NULL,
  progress REAL    CHECK (progress IS NULL OR (progress >= 0 AND progress <= 1))
);

-- Event paging per job (WHERE job_id = ? AND id > ? ORDER BY id).
CREATE INDEX job_events_job ON job_events (job_id, id);

CREATE TABLE images (
  job_id        TEXT    NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
  -- 0-based position in the upload.
  idx           INTEGER NOT NULL CHECK (idx >= 0),
  -- As sent by the client: for display only, never used as a path.
  original_name TEXT    NOT NULL,
  -- Generated file name under data/jobs/<id>/input/ (e.g. "0001.jpg").
  stored_name   TEXT    NOT NULL
                        CHECK (length(stored_name) > 0 AND instr(stored_name, '/') = 0 AND
                               instr(stored_name, '\') = 0 AND stored_name NOT IN ('.', '..')),
  bytes         INTEGER NOT NULL CHECK (bytes >= 0),
  width         INTEGER CHECK (width IS NULL OR width > 0),
  height        INTEGER CHECK (height IS NULL OR height > 0),
  -- Focal length in pixels derived from EXIF, when available: a prior, not the truth.
  exif_focal_px REAL    CHECK (exif_focal_px IS NULL OR exif_focal_px > 0),
  make          TEXT,
  model         TEXT,
  status        TEXT    NOT NULL DEFAULT 'accepted' CHECK (status IN ('accepted', 'rejected')),
  reject_reason TEXT,
  PRIMARY KEY (job_id, idx),
  UNIQUE (job_id, stored_name)
) WITHOUT ROWID;
