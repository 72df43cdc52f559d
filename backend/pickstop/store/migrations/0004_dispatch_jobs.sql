-- Jobs may also be dispatches of a plan to a vehicle over MQTT (the order followed live).
CREATE TABLE jobs_new (
    id TEXT PRIMARY KEY,
    kind TEXT NOT NULL CHECK (kind IN ('build', 'batch', 'dispatch')),
    state TEXT NOT NULL CHECK (state IN ('queued', 'running', 'done', 'failed', 'cancelled', 'interrupted')),
    progress REAL NOT NULL DEFAULT 0,
    params TEXT NOT NULL,
    result TEXT,
    error TEXT,
    created TEXT NOT NULL,
    updated TEXT NOT NULL
);
INSERT INTO jobs_new SELECT id, kind, state, progress, params, result, error, created, updated FROM jobs;
DROP TABLE jobs;
ALTER TABLE jobs_new RENAME TO jobs;
