-- The memory-mapped voxel index of a reachability database: its rows sorted by voxel key with
-- the tool pose of every stored configuration, computed once when the build completes. Each
-- file's checksum is verified when written, by `pickstop reach verify`, and on the first open
-- after its size or modification time changed (the time it was last verified at is kept).
-- index_format NULL: not indexed yet; voxels: occupied 6D voxels; reach_xy: the largest
-- horizontal tool reach [m]; index_seconds: time the indexing took [s].
ALTER TABLE reach_databases ADD COLUMN index_format INTEGER;
ALTER TABLE reach_databases ADD COLUMN voxels INTEGER;
ALTER TABLE reach_databases ADD COLUMN reach_xy REAL;
ALTER TABLE reach_databases ADD COLUMN index_seconds REAL;
CREATE TABLE IF NOT EXISTS reach_arrays (
    db_id TEXT NOT NULL REFERENCES reach_databases(id) ON DELETE CASCADE,
    name TEXT NOT NULL,                -- keys, starts, joints, manip, positions, quats
    path TEXT NOT NULL,                -- relative to the data folder (a .npy file)
    dtype TEXT NOT NULL,
    shape TEXT NOT NULL,               -- JSON list
    sha256 TEXT NOT NULL,
    bytes INTEGER NOT NULL,
    mtime_ns INTEGER NOT NULL,         -- modification time when last verified
    PRIMARY KEY (db_id, name)
)
