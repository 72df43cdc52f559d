-- Builds drop configurations with a moving link below the floor clearance: every database
-- records the clearance it kept and how many samples the floor removed (per shard and in all).
ALTER TABLE reach_databases ADD COLUMN floor_clearance REAL;
ALTER TABLE reach_databases ADD COLUMN rejected_floor INTEGER NOT NULL DEFAULT 0;
ALTER TABLE reach_shards ADD COLUMN rejected_floor INTEGER NOT NULL DEFAULT 0;
