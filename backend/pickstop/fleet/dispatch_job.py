"""A dispatch as a service job: runs in its own thread (an order can take many minutes and
must not hold up builds or batches) and writes the tracker's summary into the job record as
it goes, so ``GET /jobs/{id}`` and the planner see nodes reached and picks live."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Any

from pickstop.errors import PickStopError
from pickstop.fleet import mqtt
from pickstop.fleet import vda5050 as v
from pickstop.fleet.dispatch import DispatchCancelled, Dispatcher

log = logging.getLogger("pickstop.fleet")

#: ``set_job(job_id, **fields)`` of the service store
SetJob = Callable[..., None]


def run_dispatch_job(
    set_job: SetJob,
    job_id: str,
    order: v.Order21 | v.Order30,
    broker: mqtt.Broker,
    interface: str,
    timeout: float,
    wait_vehicle: float,
    cancelled: Callable[[], bool],
) -> None:
    set_job(job_id, state="running")

    def progress(summary: dict[str, Any]) -> None:
        n = max(1, summary["nodes"] + summary["actions"])
        done = summary["nodes_reached"] + summary["actions_finished"] + summary["actions_failed"]
        set_job(job_id, progress=min(1.0, done / n), result=summary)

    d = Dispatcher(broker, order.manufacturer, order.serial_number, order.version, interface)
    try:
        d.start()
        summary = d.run(order, timeout, wait_vehicle, progress=progress, cancelled=cancelled)
        set_job(job_id, state="done", progress=1.0, result=summary)
    except DispatchCancelled as e:
        set_job(job_id, state="cancelled", error=e.message)
    except PickStopError as e:
        set_job(job_id, state="failed", error=e.message)
    except Exception as e:  # a job must never stay 'running'
        log.exception("dispatch job %s failed", job_id)
        set_job(job_id, state="failed", error=f"{type(e).__name__}: {e}")
    finally:
        d.stop()


def start_dispatch_job(*args: Any) -> threading.Thread:
    t = threading.Thread(target=run_dispatch_job, args=args, name="pickstop-dispatch", daemon=True)
    t.start()
    return t
