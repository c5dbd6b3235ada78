"""``python -m bench.watchers``: bench.fleet's run (a fleet of fake robots doing missions) with N watchers
of the missions open meanwhile, on GET /events (server-sent events) or GET /mission/watch (NDJSON).

What it reports (bench/README.md, "Watchers"):
- delivery: every watcher must have had every transition of every mission the run completed (PENDING,
  RUNNING, COMPLETED, and each route node's): `--checked-watchers K` watchers parse every object and check
  each mission's transitions; every watcher digests its stream from the run's first mission to an
  end-of-run mission posted after the fleet's run (crc32 of the bytes with the SSE ids and keepalives
  taken out: those name each API process's own feed positions), and each digest must be one of the
  checked watchers' (`_delivery`). Digesting is C code per read, no parsing, so hundreds of watchers can
  be read on the server's own machine; dropped watchers and error events are counted;
- drain: how long after the end-of-run mission was posted every watcher had it;
- delivery latency: from the server's own time of a transition (a mission's start_timestamp for RUNNING,
  end_timestamp for COMPLETED) to the watcher's reading of it, p50/p99/max over the checked watchers, of
  the transitions in the measurement window (as every other figure) and of the whole run;
- REST latency meanwhile: GET /robot?names=... (10 robots) every PROBE_SECONDS, in the run's window;
- the server's processes' memory and CPU over time: bench.fleet's own series (the `api` group is the
  process that serves the streams).

The watchers run in `--watcher-processes` child processes (asyncio, raw HTTP/1.1), so parsing what hundreds
of watchers read does not take the generator's CPU.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import logging
import math
import multiprocessing
import re
import sys
import time
import zlib
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import datetime
from multiprocessing.connection import Connection
from typing import Any
from urllib.parse import urlsplit

import orjson

from bench import fleet, fleet_options, measure
from bench.api import DispatchApi

logger = logging.getLogger("bench")

SSE, NDJSON = "sse", "ndjson"
CONNECT_TIMEOUT = 60.0  # s for every watcher's snapshot
PROBE_SECONDS = 0.5
READ_LIMIT = 2**24  # bytes of one line (a snapshot's mission can be large)
# Children start afresh (not forked from a process with a running event loop and MQTT threads).
SPAWN = multiprocessing.get_context("spawn")


STATE_LETTERS = {"PENDING": "P", "RUNNING": "R", "COMPLETED": "C", "FAILED": "F", "CANCELED": "X"}
EVERY_TRANSITION = "PRC"  # PENDING, RUNNING, COMPLETED: of a completed mission and of each of its nodes
# A mission's JSON as GET shows it (missions.api.serializers): its name comes after the tree's nodes' names.
NAME_MARK = b',"name":"'
END_OF_RUN = "end-of-run"  # the name (after the run's prefix) of the mission posted after the fleet's run
DRAIN_TIMEOUT = 120.0  # s for every watcher to read the end-of-run mission
# What differs between watchers that read the same: SSE ids (each API process's own feed positions; "id: "
# is found only at a line's start, JSON has no space after a colon) and keepalives (each watcher's own quiet
# moments: a keepalive is a write, so a chunk, of its own).
SSE_ID = re.compile(rb"id: [^\n]*\n")
KEEPALIVE = b": keepalive"


@dataclass
class Progress:
    """A mission a watcher has seen and that has not completed yet: what it must check then."""

    states: str = ""  # its distinct states in order, one letter each (STATE_LETTERS)
    nodes: dict[str, str] = field(default_factory=dict)  # the same for each node
    last_state: str | None = None


@dataclass
class Seen:
    """What one watcher read of the run's missions, in constant memory per mission it completed (hundreds
    of watchers over thousands of missions): if `checked`, a check per mission when it completes; and a
    digest of its stream from the run's first mission to the end-of-run one."""

    checked: bool = True
    active: dict[str, Progress] = field(default_factory=dict)
    completed: int = 0
    incomplete: int = 0  # completed missions of which a transition was not read
    # transition -> read in 1-ms buckets, per second (epoch) of the transition
    latency_ms: Counter[tuple[int, int]] = field(default_factory=Counter)
    errors: list[str] = field(default_factory=list)
    objects: int = 0
    digest: int = 0  # crc32 of the stream from the run's first mission to the end-of-run one
    digested: int = 0  # bytes of it
    started: bool = False  # the run's first mission read
    ended: bool = False  # the end-of-run mission read

    def read(self, mission: dict[str, Any], read_at: float) -> None:
        name, status = mission["name"], mission["status"]
        progress = self.active.setdefault(name, Progress())
        state = status["state"]
        if state != progress.last_state:
            progress.states += STATE_LETTERS.get(state, "?")
            at = {"RUNNING": status["start_timestamp"], "COMPLETED": status["end_timestamp"]}.get(state)
            if at is not None:
                happened = _seconds(at)
                self.latency_ms[int(happened), int((read_at - happened) * 1000)] += 1
            progress.last_state = state
        for node, node_status in status["node_status"].items():
            letter = STATE_LETTERS.get(node_status["state"], "?")
            if not progress.nodes.get(node, "").endswith(letter):
                progress.nodes[node] = progress.nodes.get(node, "") + letter
        if state == "COMPLETED":
            del self.active[name]
            self.completed += 1
            self.incomplete += progress.states != EVERY_TRANSITION or any(
                states != EVERY_TRANSITION for states in progress.nodes.values()
            )

    def digest_span(self, body: bytes, *, first: bytes, last: bytes, separator: bytes) -> None:
        """Digest what of `body` (whole objects, ids taken out) lies from the object that names `first`
        to the one that names `last`, those included."""
        if self.ended:
            return
        if not self.started:
            at = body.find(first)
            if at < 0:
                return
            start = body.rfind(separator, 0, at)
            body = body[start + len(separator) :] if start >= 0 else body
            self.started = True
        at = body.find(last)
        if at >= 0:
            body = body[: body.index(separator, at) + len(separator)]
            self.ended = True
        self.digest = zlib.crc32(body, self.digest)
        self.digested += len(body)


def _seconds(timestamp: str) -> float:
    return datetime.fromisoformat(timestamp.replace("Z", "+00:00")).timestamp()


def _histogram_summary(buckets: Counter[int]) -> dict[str, float | int | None]:
    """count, p50, p99 and max in ms of 1-ms buckets (each bucket's upper bound)."""
    count = sum(buckets.values())
    if not count:
        return {"count": 0, "p50": None, "p99": None, "max": None}
    ordered = sorted(buckets.items())

    def percentile(p: float) -> int:
        rank, seen = math.ceil(p / 100 * count), 0
        for bucket, number in ordered:
            seen += number
            if seen >= rank:
                return bucket + 1
        return ordered[-1][0] + 1

    return {"count": count, "p50": percentile(50), "p99": percentile(99), "max": ordered[-1][0] + 1}


async def _watch(
    url: str, token: str | None, framing: str, prefix: str, seen: Seen, ready: asyncio.Event
) -> None:
    """One watcher: an HTTP/1.1 GET, its chunked body read as NDJSON or as server-sent events, until the
    end-of-run mission."""
    parts = urlsplit(url)
    reader, writer = await asyncio.open_connection(parts.hostname, parts.port or 80, limit=READ_LIMIT)
    auth = f"Authorization: Bearer {token}\r\n" if token else ""
    accept = "text/event-stream" if framing == SSE else "application/x-ndjson"
    target = parts.path + (f"?{parts.query}" if parts.query else "")
    writer.write(f"GET {target} HTTP/1.1\r\nHost: {parts.netloc}\r\n{auth}Accept: {accept}\r\n\r\n".encode())
    status = await reader.readline()
    if b" 200 " not in status:
        seen.errors.append(status.decode(errors="replace").strip())
        ready.set()
        return
    while (await reader.readline()).strip():
        pass  # the headers; the body is chunked
    if framing == NDJSON:
        ready.set()  # NDJSON has no end of snapshot: none of the run's missions exists yet
    separator, error_mark = (b"\n\n", b"event: error") if framing == SSE else (b"\n", b'{"error":')
    first, last = NAME_MARK + prefix.encode(), NAME_MARK + (prefix + END_OF_RUN).encode()
    pending = b""
    try:
        while not seen.ended and (size := int((await reader.readline()).split(b";")[0], 16)):
            chunk = (await reader.readexactly(size + 2))[:-2]
            if framing == SSE and chunk.startswith(KEEPALIVE):
                continue
            pending += chunk
            end = pending.rfind(separator) + len(separator)
            if end < len(separator):
                continue
            complete, pending = pending[:end], pending[end:]
            if framing == SSE:
                if not ready.is_set() and b"event: snapshot_end" in complete:
                    ready.set()
                complete = SSE_ID.sub(b"", complete)
            seen.errors += ["error event"] * complete.count(error_mark)
            if seen.checked:
                _read_objects(complete, framing, prefix, seen)
            seen.digest_span(complete, first=first, last=last, separator=separator)
    except (ConnectionError, asyncio.IncompleteReadError, ValueError) as exc:
        seen.errors.append(f"stream ended: {exc!r}")
    finally:
        ready.set()
        writer.close()


def _read_objects(body: bytes, framing: str, prefix: str, seen: Seen) -> None:
    """Check the run's missions' objects in `body` (whole objects, SSE ids taken out)."""
    read_at = time.time()
    for line in body.split(b"\n"):
        if framing == SSE:
            if not line.startswith(b'data: {"'):
                continue
            line = line[6:]
        elif not line:
            continue
        mission = orjson.loads(line)
        if "name" in mission and mission["name"].startswith(prefix):
            seen.objects += 1
            seen.read(mission, read_at)


def _watchers_process(args: dict[str, Any], count: int, pipe: Connection) -> None:
    """A child process: `count` watchers until the parent says stop; then what each saw, to the parent."""
    asyncio.run(_watchers(args, count, pipe))


async def _watchers(args: dict[str, Any], count: int, pipe: Connection) -> None:
    seen = [Seen(checked=number < args["checked"]) for number in range(count)]
    ready = [asyncio.Event() for _ in range(count)]
    tasks = [
        asyncio.create_task(_watch(args["url"], args["token"], args["framing"], args["prefix"], mine, event))
        for mine, event in zip(seen, ready, strict=True)
    ]
    await asyncio.wait_for(asyncio.gather(*(event.wait() for event in ready)), CONNECT_TIMEOUT)
    pipe.send("ready")
    # Until every watcher read the end-of-run mission (or its stream ended), or the parent stops waiting.
    stop = asyncio.get_running_loop().run_in_executor(None, pipe.recv)
    await asyncio.wait(
        [stop, asyncio.gather(*tasks, return_exceptions=True)], return_when=asyncio.FIRST_COMPLETED
    )
    pipe.send("ended")
    await stop  # "stop"
    for task in tasks:
        task.cancel()
    await asyncio.gather(*tasks, return_exceptions=True)
    for mine in seen:
        mine.active.clear()  # missions the run did not complete: nothing to check
    # Its fields, not a Seen: this module is __mp_main__ here. And the process's CPU: the clients' cost.
    pipe.send(([vars(mine) for mine in seen], time.process_time()))


def _delivery(watchers: list[Seen]) -> dict[str, Any]:
    """Missions completed and checked, and the watchers whose stream's digest is none of the checked ones'.

    Watchers served by one API process read the same bytes; those of two processes may not: each process
    reads the feed at its own moments, so changes of different objects that commit close together can
    come in another order (each object's changes keep theirs). So a watcher must have read what a checked
    watcher read, and the checked ones should cover every process (--checked-watchers)."""
    checked = [seen for seen in watchers if seen.checked]
    digests = {(seen.digest, seen.digested) for seen in checked if seen.ended}
    return {
        "missions_completed": max((seen.completed for seen in checked), default=0),
        "missions_without_every_transition": sum(seen.incomplete for seen in checked),
        "watchers_to_the_end": sum(seen.ended for seen in watchers),
        "checked_streams": len(digests),
        "bytes_digested": max((digested for _, digested in digests), default=0),
        "watchers_that_read_otherwise": sum(
            not seen.ended or (seen.digest, seen.digested) not in digests for seen in watchers
        ),
    }


def _latencies(watchers: list[Seen], window: tuple[float, float] | None = None) -> Counter[int]:
    """Delivery latencies (1-ms buckets) of the transitions that happened in `window` (epoch s; all if
    None), over every watcher."""
    buckets: Counter[int] = Counter()
    for seen in watchers:
        for (second, latency), count in seen.latency_ms.items():
            if window is None or window[0] <= second < window[1]:
                buckets[latency] += count
    return buckets


async def _probe(
    api: DispatchApi, names: list[str], samples: list[tuple[float, float]], stop: asyncio.Event
) -> None:
    """GET /robot?names=... every PROBE_SECONDS: (when, latency)."""
    while not stop.is_set():
        started = time.monotonic()
        try:
            await api.online_robots(names)
            samples.append((started, time.monotonic() - started))
        except Exception as exc:  # the run goes on; the probe's failures are counted as missing samples
            logger.warning("REST probe failed: %s", exc)
        await asyncio.sleep(PROBE_SECONDS)


async def _run(options: fleet_options.Options, args: argparse.Namespace) -> dict[str, Any]:
    # A short snapshot (the database may hold the missions of earlier runs): what is measured are the changes.
    path = (
        "/events?kind=mission&mission.most_recent=1"
        if args.framing == SSE
        else "/mission/watch?most_recent=1"
    )
    child_args = {
        "url": options.base_url.rstrip("/") + path,
        "token": options.api_token,
        "framing": args.framing,
        "prefix": options.name_prefix + "-",
    }
    counts = [len(range(i, args.watchers, args.watcher_processes)) for i in range(args.watcher_processes)]
    checked = args.watchers if args.checked_watchers is None else min(args.checked_watchers, args.watchers)
    children = []
    for number, count in enumerate(counts):
        # The checked watchers spread over the processes as the watchers are.
        mine = {**child_args, "checked": len(range(number, checked, args.watcher_processes))}
        parent, child = SPAWN.Pipe()
        process = SPAWN.Process(target=_watchers_process, args=(mine, count, child), daemon=True)
        process.start()
        children.append((process, parent))
    loop = asyncio.get_running_loop()
    for _, pipe in children:
        if not await loop.run_in_executor(None, pipe.poll, CONNECT_TIMEOUT):
            raise RuntimeError("the watchers did not connect")
        pipe.recv()
    logger.info("%d %s watchers connected", args.watchers, args.framing)
    bench = fleet.Bench(options)
    probe_api = DispatchApi(options.base_url, 1, options.api_token)
    probes: list[tuple[float, float]] = []
    stop = asyncio.Event()
    names = [load.name for load in bench.loads[:10]]
    probe = loop.create_task(_probe(probe_api, names, probes, stop))
    try:
        result = await bench.run()
    finally:
        stop.set()
        await probe
    end_of_run = child_args["prefix"] + END_OF_RUN
    tree = [{"name": "wait", "route": {"waypoints": [{"x": 0, "y": 0}]}}]
    posted = time.monotonic()
    await probe_api.post_mission({"robot": end_of_run, "name": end_of_run, "mission_tree": tree})
    probe_api.close()
    drained: float | None = None  # s until every child's watchers read the end-of-run mission
    for _, pipe in children:
        left = max(0.0, posted + DRAIN_TIMEOUT - time.monotonic())
        if not await loop.run_in_executor(None, pipe.poll, left):
            break
        pipe.recv()  # "ended"
    else:
        drained = time.monotonic() - posted
    watchers: list[Seen] = []
    clients_cpu_seconds = 0.0
    for process, pipe in children:
        pipe.send("stop")
        while (answer := await loop.run_in_executor(None, pipe.recv)) == "ended":
            pass
        seen, cpu_seconds = answer
        watchers += [Seen(**fields) for fields in seen]
        clients_cpu_seconds += cpu_seconds
        process.join(timeout=30)
    window = bench.window
    # The window in the server's clock (this machine's): the transitions it measures happened in it.
    epoch_offset = time.time() - time.monotonic()
    window_epoch = (window.start + epoch_offset, window.end + epoch_offset)
    result["watchers"] = {
        "count": args.watchers,
        "checked": checked,
        "framing": args.framing,
        "processes": args.watcher_processes,
        # The watcher processes' CPU over their whole life (connecting, the run, the drain), in seconds.
        "clients_cpu_seconds": round(clients_cpu_seconds, 1),
        "objects_read": sum(seen.objects for seen in watchers),
        "delivery": _delivery(watchers),
        "drain_seconds": None if drained is None else round(drained, 2),
        "delivery_latency_ms": _histogram_summary(_latencies(watchers, window_epoch)),
        "delivery_latency_ms_whole_run": _histogram_summary(_latencies(watchers)),
        "errors": sum(len(seen.errors) for seen in watchers),
        "error_samples": [error for seen in watchers for error in seen.errors][: fleet.MAX_LOGGED_ERRORS],
        "rest_get_robot_ms": measure.latency_summary([latency for at, latency in probes if at in window]),
    }
    return result


def markdown(result: dict[str, Any]) -> str:
    watchers = result["watchers"]
    delivery, latency = watchers["delivery"], watchers["delivery_latency_ms"]
    whole = watchers["delivery_latency_ms_whole_run"]
    rest, step = watchers["rest_get_robot_ms"], result["step_latency_ms"]
    robots = result["options"]["robots"]
    rss = result["drift"]["rss_mb"].get("api", {})
    return "\n".join(
        [
            f"## watchers: {watchers['count']} {watchers['framing']} watchers "
            f"({watchers.get('checked', watchers['count'])} checked), {robots} robots",
            "",
            "| what | value |",
            "|---|---|",
            f"| missions completed | {delivery['missions_completed']} |",
            f"| missions without every transition | {delivery['missions_without_every_transition']} |",
            "| watchers that read otherwise than the checked ones | "
            f"{delivery['watchers_that_read_otherwise']} "
            "|",
            f"| watchers that read to the end of the run | {delivery['watchers_to_the_end']} |",
            f"| every watcher at the end of the run after (s) | {watchers['drain_seconds']} |",
            f"| errors (dropped, failed) | {watchers['errors']} |",
            f"| delivery latency p50 / p99 / max ms (window) | {latency['p50']} / {latency['p99']} / "
            f"{latency['max']} |",
            f"| delivery latency p50 / p99 / max ms (whole run) | {whole['p50']} / {whole['p99']} / "
            f"{whole['max']} |",
            f"| REST GET /robot p50 / p99 ms (window) | {rest['p50']} / {rest['p99']} |",
            f"| step latency p50 / p99 ms | {step['p50']} / {step['p99']} |",
            f"| api RSS over the window, first / last / max (MB) | {rss.get('first')} / {rss.get('last')} / "
            f"{rss.get('max')} |",
            f"| watcher clients' CPU, whole run (s) | {watchers['clients_cpu_seconds']} |",
            f"| CPU speed (ms of calibration work) | {result['machine']['cpu_speed_ms']} |",
            "",
        ]
    )


WATCHER_OPTIONS = {"watchers", "framing", "watcher_processes", "checked_watchers"}  # not bench.fleet's


def main(argv: Sequence[str] | None = None) -> int:
    parser = fleet_options.build_parser()
    parser.prog = "python -m bench.watchers"
    parser.add_argument("--watchers", type=int, default=10, help="concurrent watchers")
    parser.add_argument(
        "--framing", choices=(SSE, NDJSON), default=SSE, help="GET /events or GET /mission/watch"
    )
    parser.add_argument(
        "--watcher-processes", type=int, default=2, help="child processes the watchers run in"
    )
    parser.add_argument(
        "--checked-watchers",
        type=int,
        default=None,
        help="watchers that parse and check every object (default all); the others digest their stream only",
    )
    args = parser.parse_args(argv)
    if args.checked_watchers is not None and args.checked_watchers < 1:
        parser.error("--checked-watchers: at least 1 (the others are compared with the checked ones)")
    logging.basicConfig(level=args.log_level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    options = fleet_options.options_from(
        argparse.Namespace(**{k: v for k, v in vars(args).items() if k not in WATCHER_OPTIONS}),
        args.robots,
    )
    result = asyncio.run(_run(options, args))
    options.output.mkdir(parents=True, exist_ok=True)
    stem = f"watchers-n{options.robots}-w{args.watchers}-{options.run_id}"
    (options.output / f"{stem}.json").write_text(json.dumps(result, indent=2) + "\n")
    (options.output / f"{stem}.md").write_text(markdown(result))
    logger.info("wrote %s\n%s", options.output / f"{stem}.json", markdown(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
