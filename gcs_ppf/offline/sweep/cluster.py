"""A sweep's batches planned on a Ray cluster (Ray is the optional ``cluster`` extra).

Each batch is one Ray task running ``plan_batch``, the function the local pool runs, so a
cluster gives the same rows. Every node needs the same gcs-ppf (and numba's cache builds
itself on each node the first time).
"""

from __future__ import annotations

from collections.abc import Sequence

from gcs_ppf.offline.sweep.batches import Batch, Progress, plan_batch
from gcs_ppf.offline.sweep.rows import SceneRow

LOCAL = "local"
"""The address that starts a Ray on this machine for the sweep (stopped after it)."""


class ClusterError(RuntimeError):
    """Ray is missing, or there is no Ray to plan on."""


def plan_on_ray(
    batches: Sequence[Batch],
    address: str | None,
    progress: Progress,
    *,
    num_cpus: int | None = None,
) -> list[SceneRow]:
    """Plan the batches as Ray tasks; rows as the batches finish.

    ``address``: ``"local"`` starts a Ray here with ``num_cpus`` CPUs and stops it after;
    any other is given to ``ray.init`` (``"auto"``, ``"HEAD:6379"`` on a cluster's node,
    ``"ray://HEAD:10001"`` from outside it), and the connection closed after; None uses the
    Ray this process has already joined (``ray.init`` called before).
    """
    try:
        import ray
    except ImportError:
        raise ClusterError("Ray is not installed: pip install 'gcs-ppf[cluster]'") from None
    joined = False
    if address is not None and not ray.is_initialized():
        if address == LOCAL:
            ray.init(num_cpus=num_cpus, include_dashboard=False)
        else:
            ray.init(address=address)
        joined = True
    elif not ray.is_initialized():
        raise ClusterError("no Ray to plan on: give an address, or call ray.init() first")
    try:
        task = ray.remote(plan_batch)
        pending = [task.remote(batch) for batch in batches]
        rows: list[SceneRow] = []
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                got: list[SceneRow] = ray.get(ref)
                progress(got)
                rows.extend(got)
        return rows
    finally:
        if joined:
            ray.shutdown()
