"""The SUMO network is built by netconvert once per road spec and reused from the cache."""

from __future__ import annotations

import dataclasses

import pytest

import scenarios.network as network
from scenarios.loader import load_scenario

pytestmark = pytest.mark.sumo


def test_network_cached_by_road_hash(tmp_path, monkeypatch):
    monkeypatch.setenv("MERGE_IRL_CACHE", str(tmp_path))
    road = load_scenario("synthetic").road
    calls = []
    real = network.netconvert_binary
    monkeypatch.setattr(network, "netconvert_binary", lambda: calls.append(1) or real())
    net = network.build_network(road)
    assert net.is_file() and net.parent.parent == tmp_path / "networks"
    mtime = net.stat().st_mtime_ns
    again = network.build_network(road)
    assert again == net and again.stat().st_mtime_ns == mtime and len(calls) == 1
    # no temporary build folders are left behind
    assert [p.name for p in (tmp_path / "networks").iterdir()] == [net.parent.name]
    other = network.build_network(dataclasses.replace(road, aux_length_m=road.aux_length_m + 10))
    assert other != net and len(calls) == 2


def test_network_geometry(tmp_path, monkeypatch):
    import sumolib

    monkeypatch.setenv("MERGE_IRL_CACHE", str(tmp_path))
    spec = load_scenario("i80")
    net = sumolib.net.readNet(str(network.build_network(spec.road)))
    aux = net.getEdge("aux")
    assert aux.getLaneNumber() == 7 and net.getEdge("main_in").getLaneNumber() == 6
    # the auxiliary lane (SUMO index 0) is the rightmost one and has no successor
    assert aux.getLane(0).getShape()[0][1] < aux.getLane(1).getShape()[0][1]
    assert not aux.getLane(0).getOutgoing()
    # the main road starts at x = 0 (no offset) and runs along +x
    x0, _ = net.getEdge("main_in").getLane(0).getShape()[0]
    assert abs(x0) < 1e-6
    assert net.getEdge("ramp").getToNode().getID() == "merge"
