-- The REST service's records: scenes (versioned by ETag), immutable plans, jobs, robots.
CREATE TABLE IF NOT EXISTS scenes (
    id TEXT PRIMARY KEY,
    name TEXT NOT NULL,
    doc TEXT NOT NULL,                 -- the scene document (JSON)
    etag TEXT NOT NULL,                -- changes with every update
    revision INTEGER NOT NULL,
    created TEXT NOT NULL,
    updated TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS plans (
    id TEXT PRIMARY KEY,
    scene_id TEXT,                     -- NULL for an inline scene; kept when the scene is deleted
    scene_revision INTEGER,
    scene_doc TEXT NOT NULL,           -- the exact input
    options TEXT NOT NULL,
    doc TEXT NOT NULL,                 -- the plan document
    created TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS plans_scene ON plans(scene_id, created);
CREATE TABLE IF NOT EXISTS jobs (
    id TEXT PRIMARY KEY,
    kind TEXT NOT NULL CHECK (kind IN ('build', 'batch')),
    state TEXT NOT NULL CHECK (state IN ('queued', 'running', 'done', 'failed', 'cancelled', 'interrupted')),
    progress REAL NOT NULL DEFAULT 0,
    params TEXT NOT NULL,
    result TEXT,
    error TEXT,
    created TEXT NOT NULL,
    updated TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS robots (
    name TEXT PRIMARY KEY,
    config TEXT NOT NULL,
    created TEXT NOT NULL
);
