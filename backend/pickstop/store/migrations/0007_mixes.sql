-- Product mixes: every order of a mix planned on one layout (each order's plan is a plan
-- record; the mix document names them). Jobs may also plan a mix or search a layout.
CREATE TABLE IF NOT EXISTS mixes (
    id TEXT PRIMARY KEY,
    scene_id TEXT,                     -- NULL for an inline scene; kept when the scene is deleted
    scene_revision INTEGER,
    options TEXT NOT NULL,
    doc TEXT NOT NULL,                 -- the mix document, each order's plan by its plan id
    created TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS mixes_scene ON mixes(scene_id, created);
CREATE TABLE jobs_new (
    id TEXT PRIMARY KEY,
    kind TEXT NOT NULL CHECK (kind IN ('build', 'batch', 'dispatch', 'mix', 'layout')),
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
