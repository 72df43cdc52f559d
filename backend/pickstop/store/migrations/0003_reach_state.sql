-- Builds that stopped before completing are 'interrupted' (resumed by the same command);
-- a running build records who runs it; every database records its self-collision screen's
-- false rejection, measured against exact coal checks for the robot it was built for.
CREATE TABLE reach_databases_new (
    id TEXT PRIMARY KEY,
    robot TEXT NOT NULL,
    robot_hash TEXT NOT NULL,
    dof INTEGER NOT NULL,
    resolution REAL NOT NULL,
    orientation INTEGER NOT NULL,
    samples INTEGER NOT NULL,
    seed INTEGER NOT NULL,
    chunk_size INTEGER NOT NULL,
    thinning REAL NOT NULL,
    code_version TEXT NOT NULL,
    joint_lower TEXT NOT NULL,
    joint_upper TEXT NOT NULL,
    state TEXT NOT NULL CHECK (state IN ('building', 'complete', 'interrupted')),
    created TEXT NOT NULL,
    completed TEXT,
    build_seconds REAL NOT NULL DEFAULT 0,
    stored INTEGER NOT NULL DEFAULT 0,
    rejected_self_collision INTEGER NOT NULL DEFAULT 0,
    rejected_thinning INTEGER NOT NULL DEFAULT 0,
    builder TEXT,                      -- "host pid" of the process building it, while it does
    screen_false_rejection REAL,       -- valid configurations the screen drops (fraction)
    screen_flagged REAL,               -- configurations the screen flags (fraction)
    screen_samples INTEGER             -- random configurations behind both figures
);
INSERT INTO reach_databases_new (
    id, robot, robot_hash, dof, resolution, orientation, samples, seed, chunk_size, thinning,
    code_version, joint_lower, joint_upper, state, created, completed, build_seconds, stored,
    rejected_self_collision, rejected_thinning
) SELECT
    id, robot, robot_hash, dof, resolution, orientation, samples, seed, chunk_size, thinning,
    code_version, joint_lower, joint_upper,
    CASE state WHEN 'building' THEN 'interrupted' ELSE state END,
    created, completed, build_seconds, stored, rejected_self_collision, rejected_thinning
FROM reach_databases;
DROP TABLE reach_databases;
ALTER TABLE reach_databases_new RENAME TO reach_databases;
CREATE INDEX IF NOT EXISTS reach_databases_robot ON reach_databases(robot, state);
