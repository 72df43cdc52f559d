"""The speed-ups that wrap the from-scratch region pipeline, each tested equal to it.

The pipeline (:mod:`pickstop.regions.pipeline`, :mod:`pickstop.regions.solve`) reads from
scratch and asks one small strategy, :class:`~pickstop.regions.recall.Recall`, where work done
before may stand in. Here are what answers it across layouts and what keeps regions between
requests: the memo of refinements, cell answers, exact checks and grown witnesses per tray
(:mod:`~pickstop.speedups.region_memo`, :mod:`~pickstop.speedups.checked`), the recall over it
(:mod:`~pickstop.speedups.cell_recall`), the region planner with its caches, validity rules,
carried previews and worker processes (:mod:`~pickstop.speedups.region_planner`,
:mod:`~pickstop.speedups.validity`, :mod:`~pickstop.speedups.carry`), and the warm-up of the
compiled kernels (:mod:`~pickstop.speedups.warmup`). ``tests/sequence/test_pure.py`` holds
the planner's regions and plans against the pipeline's from scratch over random edits.
"""
