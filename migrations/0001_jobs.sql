-- The job store's schema (src/server/store/postgres.rs). JSON is kept as text, never jsonb:
-- results are served byte for byte (jsonb reorders keys and rewrites numbers).

CREATE TABLE jobs (
    id               text PRIMARY KEY,
    kind             text NOT NULL,
    state            text NOT NULL,
    priority         int NOT NULL DEFAULT 0,
    created_ms       bigint NOT NULL,
    started_ms       bigint,
    finished_ms      bigint,
    time_limit       float8 NOT NULL,
    request          text NOT NULL,
    progress         text,
    error            text,
    warnings         text NOT NULL DEFAULT '[]',
    max_attempts     int NOT NULL DEFAULT 1,
    attempt          int NOT NULL DEFAULT 0,
    owner            text,
    lease_until      timestamptz,
    cancel_requested bool NOT NULL DEFAULT false,
    last_seq         bigint NOT NULL DEFAULT 0,
    result           text,
    result_bytes     bigint NOT NULL DEFAULT 0
);

-- The claim: the next queued job, highest priority first, then oldest.
CREATE INDEX jobs_queue ON jobs (priority DESC, created_ms, id) WHERE state = 'queued';
-- Keyset paging of GET /v1/plans, newest first.
CREATE INDEX jobs_created ON jobs (created_ms DESC, id DESC);
-- The reaper: running jobs by lease deadline.
CREATE INDEX jobs_running ON jobs (lease_until) WHERE state = 'running';
-- Retention: finished jobs by age.
CREATE INDEX jobs_finished ON jobs (finished_ms) WHERE finished_ms IS NOT NULL;

CREATE TABLE events (
    job_id text NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    seq    bigint NOT NULL,
    name   text NOT NULL,
    data   text NOT NULL,
    PRIMARY KEY (job_id, seq)
);

CREATE TABLE resources (
    kind       text NOT NULL,
    name       text NOT NULL,
    body       bytea NOT NULL,
    updated_ms bigint NOT NULL,
    PRIMARY KEY (kind, name)
);

CREATE TABLE blobs (
    kind       text NOT NULL,
    key        text NOT NULL,
    bytes      bytea NOT NULL,
    created_ms bigint NOT NULL,
    PRIMARY KEY (kind, key)
);
