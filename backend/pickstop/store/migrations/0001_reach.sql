-- Reachability databases and their parquet shards.
CREATE TABLE IF NOT EXISTS reach_databases (
    id TEXT PRIMARY KEY,
    robot TEXT NOT NULL,
    robot_hash TEXT NOT NULL,
    dof INTEGER NOT NULL,
    resolution REAL NOT NULL,          -- position voxel edge [m]
    orientation INTEGER NOT NULL,      -- SO(3) cells per cube-face edge
    samples INTEGER NOT NULL,
    seed INTEGER NOT NULL,
    chunk_size INTEGER NOT NULL,
    thinning REAL NOT NULL,            -- manipulability reference w_ref (0 = off)
    code_version TEXT NOT NULL,
    joint_lower TEXT NOT NULL,         -- JSON list, quantisation range [rad or m]
    joint_upper TEXT NOT NULL,
    state TEXT NOT NULL CHECK (state IN ('building', 'complete')),
    created TEXT NOT NULL,
    completed TEXT,
    build_seconds REAL NOT NULL DEFAULT 0,
    stored INTEGER NOT NULL DEFAULT 0,
    rejected_self_collision INTEGER NOT NULL DEFAULT 0,
    rejected_thinning INTEGER NOT NULL DEFAULT 0
);
CREATE TABLE IF NOT EXISTS reach_shards (
    db_id TEXT NOT NULL REFERENCES reach_databases(id) ON DELETE CASCADE,
    chunk INTEGER NOT NULL,
    path TEXT NOT NULL,                -- relative to the data folder
    sha256 TEXT NOT NULL,
    bytes INTEGER NOT NULL,
    rows INTEGER NOT NULL,
    samples INTEGER NOT NULL,
    rejected_self_collision INTEGER NOT NULL,
    rejected_thinning INTEGER NOT NULL,
    seconds REAL NOT NULL,
    PRIMARY KEY (db_id, chunk)
);
CREATE INDEX IF NOT EXISTS reach_databases_robot ON reach_databases(robot, state);
