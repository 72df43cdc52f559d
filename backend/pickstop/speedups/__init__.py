"""The speed-ups that wrap the from-scratch pipeline, each tested equal to it.

The region pipeline (:mod:`pickstop.regions.pipeline`, :mod:`pickstop.regions.solve`) reads
from scratch and asks one small strategy, :class:`~pickstop.regions.recall.Recall`, where work
done before may stand in; the stop pipeline (:mod:`pickstop.sequence.request` over
:class:`~pickstop.sequence.steps.PlanSteps`) runs its steps through one interface too. Here
are what answers them faster:

- the memo of refinements, cell answers, exact checks and grown witnesses per tray
  (:mod:`~pickstop.speedups.region_memo`, :mod:`~pickstop.speedups.checked`) and the recall
  over it (:mod:`~pickstop.speedups.cell_recall`);
- the region planner with its caches, validity rules, carried previews and worker processes
  (:mod:`~pickstop.speedups.region_planner`, :mod:`~pickstop.speedups.validity`,
  :mod:`~pickstop.speedups.carry`) and the warm-up of the compiled kernels
  (:mod:`~pickstop.speedups.warmup`);
- the stop planner, every plan step behind a bounded cache, with prefetched selections and
  checks (:mod:`~pickstop.speedups.stop_planner`).

``tests/sequence/test_pure.py`` holds the planners' regions and plans against the pipelines
from scratch over random edits; ``tests/sequence/test_examples.py`` holds the example plans
against stored documents.
"""
