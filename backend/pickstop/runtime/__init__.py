"""How PickStop runs: one cancellation token per computation, the plan-ahead policy, and every
process it starts.

- :mod:`~pickstop.runtime.cancel`: the token, its checkpoints and ``Work``, a computation on a
  thread stopped by its token (the core takes only this module).
- :mod:`~pickstop.runtime.plan_ahead`: when the planner works ahead of the requests.
- :mod:`~pickstop.runtime.planner_process`: the service's planner in a child process.
- :mod:`~pickstop.runtime.region_processes`: region helpers forked from a planner.
- :mod:`~pickstop.runtime.servers`: API servers forked on one port (``serve --workers``).
- :mod:`~pickstop.runtime.build_process`: a database build in a process group of its own.
- :mod:`~pickstop.runtime.yaml_decoders`: warm children that decode YAML request bodies.

``docs/architecture.md`` draws the process tree and where each token is cancelled.
"""
