-- Each stored plan's tolerances proven by the exact check (per stop: circle, ellipse, yaw
-- window), made on the first export or dispatch that asks for them; plans never change.
CREATE TABLE IF NOT EXISTS plan_proofs (
    plan_id TEXT PRIMARY KEY REFERENCES plans(id) ON DELETE CASCADE,
    prover TEXT NOT NULL,              -- the method and its constants (fleet/proof.py PROVER)
    doc TEXT NOT NULL,                 -- the proof (JSON)
    created TEXT NOT NULL
);
