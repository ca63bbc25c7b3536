"""A local Dask cluster listens on the loopback interface only (issue 39, item 6)."""

from __future__ import annotations

import ipaddress

import psutil
import pytest

from pneufdd.parallel import LOOPBACK, executor, local_cluster

pytestmark = pytest.mark.filterwarnings(
    "ignore:Creating scratch directories is taking a surprisingly long time"
)


def _listening(process: psutil.Process) -> list[tuple[str, int]]:
    """Every (address, port) a process listens on over TCP."""
    return [
        (c.laddr.ip, c.laddr.port)
        for c in process.net_connections(kind="inet")
        if c.status == psutil.CONN_LISTEN
    ]


def test_local_cluster_listens_on_loopback_only() -> None:
    me = psutil.Process()
    before = set(_listening(me))
    with local_cluster(2) as cluster:
        cluster.wait_for_workers(2)  # type: ignore[no-untyped-call]
        ours = set(_listening(me)) - before
        for child in me.children(recursive=True):
            ours |= set(_listening(child))
        # scheduler, its dashboard, 2 nannies, 2 workers and their dashboards at least
        assert len(ours) >= 6, ours
        for ip, port in ours:
            assert ipaddress.ip_address(ip).is_loopback, (ip, port)
        addresses = [cluster.scheduler_address, *cluster.scheduler_info["workers"]]
        assert all(f"//{LOOPBACK}:" in a for a in addresses), addresses
        assert cluster.dashboard_link.startswith(f"http://{LOOPBACK}:")


def test_executor_uses_the_loopback_cluster() -> None:
    with executor(workers=2) as pool:
        assert pool is not None
        client = pool._client  # type: ignore[attr-defined]
        assert client.scheduler.address.startswith(f"tcp://{LOOPBACK}:")
        assert sorted(pool.map(abs, [-1, -2])) == [1, 2]
