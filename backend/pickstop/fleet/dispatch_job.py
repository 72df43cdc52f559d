"""A dispatch as a service job: runs in its own thread (an order can take many minutes and
must not hold up builds or batches) and writes the tracker's summary into the job record as
it goes, so ``GET /jobs/{id}`` and the planner see nodes reached and picks live."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pickstop.errors import PickStopError
from pickstop.fleet import mqtt
from pickstop.fleet.dispatch import BuildOrder, DispatchCancelled, Dispatcher, checked_order
from pickstop.fleet.vehicle_types import VehicleTypes

log = logging.getLogger("pickstop.fleet")

#: ``set_job(job_id, **fields)`` of the service store
SetJob = Callable[..., None]


@dataclass(frozen=True)
class DispatchJob:
    """What a dispatch job sends, to which vehicle, and how long it waits [s]."""

    build: BuildOrder
    manufacturer: str
    serial_number: str
    version: str
    interface: str
    timeout: float
    wait_vehicle: float
    types: VehicleTypes = field(default_factory=VehicleTypes)
    vehicle_type: str | None = None
    factsheet: bool = True


def run_dispatch_job(
    set_job: SetJob,
    job_id: str,
    job: DispatchJob,
    broker: mqtt.Broker,
    cancelled: Callable[[], bool],
) -> None:
    """Read the factsheet, check and send the order, follow it; the job record as it goes."""
    set_job(job_id, state="running")

    def progress(summary: dict[str, Any]) -> None:
        n = max(1, summary["nodes"] + summary["actions"])
        done = summary["nodes_reached"] + summary["actions_finished"] + summary["actions_failed"]
        set_job(job_id, progress=min(1.0, done / n), result=summary)

    d = Dispatcher(broker, job.manufacturer, job.serial_number, job.version, job.interface)
    try:
        d.start()
        order, vt = checked_order(
            d, job.build, job.types, job.vehicle_type, job.factsheet, job.wait_vehicle
        )
        summary = d.run(
            order, job.timeout, job.wait_vehicle, progress=progress, cancelled=cancelled,
            pick=None if vt is None else vt.pick,
        )  # fmt: skip
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
