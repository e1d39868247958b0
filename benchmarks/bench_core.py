"""Throughput of the YAFS-compatible core, and its speed against YAFS3 on YAFS3's own scripts.

**Synthetic** (default): 1 user - 1 access point - 5 edge servers; every request is
multicast to all 5 servers (5 copies), each copy is served and answered back to the user's
sink; default YAFS delay hooks (``yafs3`` engine, link queues on) and result files written to a
temporary directory. Prints request copies per wall-clock second, result rows (module +
sink + link rows) per second and the peak resident memory (rates per wall-clock second,
and per CPU second of this process, which is what the wall figure would be on an otherwise
idle machine); then the same with a concurrent service model (``direct`` engine, what the
edge model uses) and with result files off.

**Against YAFS3** (``--yafs3 PATH``, a checkout of YAFS's ``YAFS3`` branch: ``PATH/src/yafs``,
``PATH/tutorial_scenarios``, ``PATH/examples``): each of YAFS3's tutorial and example
scripts is copied twice into a temporary folder, once as is and once with its ``yafs``
imports rewritten to ``yafs_safetail.yafs`` (nothing else changes), and the two are run in
turn, ``--repeats`` times each, alternating. Each run times ``Sim.run`` only (a
``sitecustomize`` in the temporary folder wraps it); it also gives the scripts Python 3.10's
``random.sample`` on sets (YAFS3's scripts call it on networkx node views; 3.11 refuses)
and seeds the global generators identically for both libraries (one script never seeds).
Printed per script: median ``Sim.run`` seconds of each, the ratio of the medians, the
median of the per-pair ratios, and whether the two libraries wrote byte-identical CSVs.
``--split`` also times the scripts' own selection, placement, population and monitor code
called from ``Sim.run`` (the same code on both sides) and prints the ratio without it, and the
ceiling: YAFS3's ``Sim.run`` over the time our ``Sim.run`` spends in that script code, the
ratio a core that took no time at all would reach on that script.

Run: ``python benchmarks/bench_core.py [--requests 20000]``
     ``python benchmarks/bench_core.py --yafs3 PATH [--repeats 5] [--scripts NAME ...] [--cpu] [--split]``
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from yafs_safetail.yafs.application import Application, Message
from yafs_safetail.yafs.core import Sim
from yafs_safetail.yafs.distribution import deterministic_distribution
from yafs_safetail.yafs.hooks import YAFSServiceModel
from yafs_safetail.yafs.placement import Placement
from yafs_safetail.yafs.population import Population
from yafs_safetail.yafs.selection import Selection
from yafs_safetail.yafs.topology import Topology

USER, ACCESS_POINT = 0, 1
SERVERS = [2, 3, 4, 5, 6]
PERIOD = 1.0


class MulticastToAll(Selection):
    """Requests to every server replica; replies back to the user's sink (paths precomputed)."""

    def __init__(self) -> None:
        super().__init__()
        self.completed = 0
        self._up: tuple[list[list[int]], list[int]] | None = None
        self._down: dict[int, tuple[list[list[int]], list[int]]] = {}

    def get_path(self, sim, app_name, message, topology_src, alloc_DES, alloc_module, traffic, from_des):
        if message.name == "Req":
            if self._up is None:
                replicas = alloc_module[app_name]["Service"]
                self._up = ([[USER, ACCESS_POINT, alloc_DES[d]] for d in replicas], list(replicas))
            return self._up
        down = self._down.get(topology_src)
        if down is None:
            sink = alloc_module[app_name]["Client"][0]
            down = ([[topology_src, ACCESS_POINT, USER]], [sink])
            self._down[topology_src] = down
        return down

    def on_request_complete(self, sim, outcome):
        self.completed += 1


class OnServers(Placement):
    def initial_allocation(self, sim, app_name):
        services = sim.apps[app_name].services["Service"]
        for node in SERVERS:
            sim.deploy_module(app_name, "Service", services, [node])


class OneUser(Population):
    def initial_allocation(self, sim, app_name):
        app = sim.apps[app_name]
        sim.deploy_source(app_name, id_node=USER, msg=app.get_message("Req"),
                          distribution=deterministic_distribution(PERIOD))
        sim.deploy_sink(app_name, node=USER, module="Client")


class ConcurrentService(YAFSServiceModel):
    concurrent = True


def build(results_path: str | None, service_model=None) -> tuple[Sim, MulticastToAll]:
    topology = Topology()
    topology.load({
        "entity": [{"id": USER, "IPT": 1}, {"id": ACCESS_POINT, "IPT": 1}]
        + [{"id": s, "IPT": 1000 * (i + 1)} for i, s in enumerate(SERVERS)],
        "link": [{"s": USER, "d": ACCESS_POINT, "BW": 100, "PR": 0.002}]
        + [{"s": ACCESS_POINT, "d": s, "BW": 50, "PR": 0.005 * (i + 1)} for i, s in enumerate(SERVERS)],
    })
    app = Application("safetail")
    app.set_modules([{"User": {"Type": Application.TYPE_SOURCE}},
                     {"Service": {"RAM": 1, "Type": Application.TYPE_MODULE}},
                     {"Client": {"Type": Application.TYPE_SINK}}])
    request = Message("Req", "User", "Service", instructions=100, bytes=200_000)
    reply = Message("Resp", "Service", "Client", instructions=0, bytes=50_000)
    app.add_source_messages(request)
    app.add_service_module("Service", request, reply)
    sim = Sim(topology, default_results_path=results_path, service_model=service_model,
              write_results=results_path is not None)
    selection = MulticastToAll()
    sim.deploy_app(app, OnServers("servers"), OneUser("user"), selection)
    return sim, selection


def measure(label: str, requests: int, results_dir: Path | None, service_model=None) -> None:
    path = str(results_dir / label) if results_dir is not None else None
    sim, selection = build(path, service_model)
    start, start_cpu = time.perf_counter(), time.process_time()
    sim.run(requests * PERIOD + PERIOD / 2)
    wall_s = time.perf_counter() - start
    cpu_s = time.process_time() - start_cpu
    copies = selection.completed * len(SERVERS)
    rows = 0
    if path is not None:
        for suffix in (".csv", "_link.csv"):
            with open(path + suffix, "rb") as handle:
                rows += sum(1 for _ in handle) - 1
    peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"{label:<24} requests={selection.completed:>6}  wall={wall_s:5.2f} s "
          f"(cpu {cpu_s:5.2f} s)  copies/s={copies / wall_s:>7,.0f} (cpu {copies / cpu_s:>7,.0f})  "
          f"rows/s={rows / wall_s:>8,.0f} (cpu {rows / cpu_s:>8,.0f})  peak RSS={peak_mib:5.1f} MiB")


# ---------------------------------------------------------------------------- against YAFS3

REPOSITORY = Path(__file__).resolve().parents[1]

#: YAFS3's tutorial and example scripts (paths inside a YAFS3 checkout).
YAFS3_SCRIPTS = (
    "tutorial_scenarios/01_basicExample/main.py",
    "tutorial_scenarios/02_serviceMovement/main.py",
    "tutorial_scenarios/03_topologyChanges/main.py",
    "tutorial_scenarios/04_userMovement/main.py",
    "examples/Tutorial/main1.py",
    "examples/Tutorial/main2.py",
    "examples/Tutorial/main3.py",
    "examples/ConquestService/main.py",
    "examples/DynamicAllocation/main.py",
    "examples/DynamicFailuresOnNodes/main.py",
    "examples/DynamicWorkload/main.py",
    "examples/TestJsons/main.py",
    "examples/Tutorial_JSONModelling/main.py",
    "examples/VRGameFog-IFogSim-WL/main.py",
)

# Written into the runs' folder as sitecustomize.py (benchmark tooling, not the core).
_SITECUSTOMIZE = """
import os, random, sys, time
from collections.abc import Set

_sample = random.Random.sample
def _sample_sets(self, population, k, *, counts=None):
    # Python 3.10 accepted sets (it took a tuple of them); YAFS3's scripts rely on it.
    if isinstance(population, Set):
        population = tuple(population)
    return _sample(self, population, k, counts=counts)
random.Random.sample = _sample_sets
random.sample = random._inst.sample

random.seed(0)
try:
    import numpy
    numpy.random.seed(0)
except ImportError:
    pass

_clock = time.process_time if os.environ.get("BENCH_CPU") else time.perf_counter
_spent = [0.0, 0.0]  # Sim.run, and the scripts' own code called from it

def _timed_user(function):
    def call(*args, **kwargs):
        start = _clock()
        try:
            return function(*args, **kwargs)
        finally:
            _spent[1] += _clock() - start
    call._bench_user = True
    return call

def _from_script(obj):
    # Defined in the script's own folder (not in YAFS or in this core)?
    code = getattr(obj, "__code__", None)
    if code is None:
        module = sys.modules.get(type(obj).__module__)
        filename = getattr(module, "__file__", None) or ""
    else:
        filename = code.co_filename
    return os.path.abspath(filename).startswith(os.getcwd() + os.sep)

def _mark_user(obj, names):
    # The script's selection / placement / population methods, timed as the script's code.
    if not _from_script(obj):
        return
    for name in names:
        method = getattr(obj, name, None)
        if method is not None and not getattr(method, "_bench_user", False):
            try:
                setattr(obj, name, _timed_user(method))
            except AttributeError:
                pass

class _TimeRun:
    def find_spec(self, name, path, target=None):
        if name not in ("yafs.core", "yafs_safetail.yafs.core"):
            return None
        import importlib.machinery
        spec = importlib.machinery.PathFinder.find_spec(name, path)
        load = spec.loader.exec_module
        def exec_module(module):
            load(module)
            run = module.Sim.run
            def timed(self, *args, **kwargs):
                start = _clock()
                try:
                    return run(self, *args, **kwargs)
                finally:
                    _spent[0] += _clock() - start
            module.Sim.run = timed
            if not os.environ.get("BENCH_SPLIT"):
                return
            for deploy in ("deploy_app", "deploy_app2"):
                original = getattr(module.Sim, deploy)
                def deploy_timed(self, *args, _original=original, **kwargs):
                    for obj in list(args) + list(kwargs.values()):
                        _mark_user(obj, ("get_path", "get_path_from_failure", "initial_allocation", "run"))
                    return _original(self, *args, **kwargs)
                setattr(module.Sim, deploy, deploy_timed)
            monitor = module.Sim.deploy_monitor
            def monitor_timed(self, name, function, distribution, **param):
                if _from_script(function):
                    function = _timed_user(function)
                return monitor(self, name, function, distribution, **param)
            module.Sim.deploy_monitor = monitor_timed
        spec.loader.exec_module = exec_module
        return spec
sys.meta_path.insert(0, _TimeRun())

import atexit
@atexit.register
def _report():
    with open(os.environ["BENCH_TIME_FILE"], "w") as handle:
        handle.write("%r %r" % tuple(_spent))
"""

_IMPORTS = (
    (re.compile(r"^(\s*)from yafs(\.[\w.]+)? import", re.M), r"\1from yafs_safetail.yafs\2 import"),
    (re.compile(r"^(\s*)import yafs(\.[\w.]+)?\s*$", re.M), r"\1import yafs_safetail.yafs\2 as yafs\2"),
)


def port_imports(folder: Path) -> None:
    """Rewrite the ``yafs`` imports of every ``.py`` file under ``folder``; nothing else."""
    for path in folder.rglob("*.py"):
        text = path.read_text(encoding="utf-8", errors="surrogateescape")
        ported = text
        for pattern, replacement in _IMPORTS:
            ported = pattern.sub(replacement, ported)
        if ported != text:
            path.write_text(ported, encoding="utf-8", errors="surrogateescape")


def run_script(folder: Path, script: str, library: Path, site: Path, cpu: bool,
               timeout_s: float, split: bool = False) -> tuple[tuple[float, float] | None, list[Path]]:
    """Run ``script`` in ``folder`` with ``library`` first on the path; return its
    ``Sim.run`` seconds and (with ``split``; else 0) the part of them spent in the script's
    own selection, placement, population and monitor code (None if it failed before
    writing any), and the CSVs it wrote."""
    time_file = folder / ".sim_run_s"
    time_file.unlink(missing_ok=True)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), str(library), str(folder)]),
               MPLBACKEND="Agg", BENCH_TIME_FILE=str(time_file), PYTHONHASHSEED="0")
    env.pop("BENCH_CPU", None)
    env.pop("BENCH_SPLIT", None)
    if cpu:
        env["BENCH_CPU"] = "1"
    if split:
        env["BENCH_SPLIT"] = "1"
    start = time.time() - 1.0
    try:
        subprocess.run([sys.executable, Path(script).name], cwd=folder, env=env, timeout=timeout_s,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
    except subprocess.TimeoutExpired:
        return None, []
    csvs = sorted(p for p in folder.rglob("*.csv") if p.stat().st_mtime >= start)
    seconds = tuple(map(float, time_file.read_text().split())) if time_file.exists() else None
    return seconds, csvs


def compare_with_yafs3(yafs3: Path, scripts: list[str], repeats: int, cpu: bool, timeout_s: float,
                      split: bool = False) -> int:
    """Run each script on YAFS3 and on this core in turn; print times, ratios, CSV equality."""
    library = yafs3 / "src"
    if not (library / "yafs" / "core.py").exists():
        print(f"{yafs3}: no src/yafs/core.py (expected a checkout of YAFS's YAFS3 branch)")
        return 2
    clock = "CPU" if cpu else "wall"
    print(f"Python {sys.version.split()[0]}; Sim.run {clock} seconds, median of {repeats} alternating runs")
    if split:
        print("'core': Sim.run minus the time spent in the script's own selection, placement, population")
        print("and monitor classes/functions (defined in the script's folder; the same code on both sides;")
        print("timing them adds a little to both sides' Sim.run); 'ceiling': YAFS3's Sim.run over our")
        print("time in that script code, the ratio a core taking no time at all would reach")
    print(f"{'script':<46} {'YAFS3 s':>9} {'ours s':>9} {'ratio':>7} {'pair med':>8} "
          + (f"{'core YAFS3':>10} {'core ours':>9} {'ratio':>7} {'ceiling':>8}  " if split else "") + "CSVs")
    with tempfile.TemporaryDirectory() as tmp:
        site = Path(tmp) / "site"
        site.mkdir()
        (site / "sitecustomize.py").write_text(_SITECUSTOMIZE)
        for script in scripts:
            source = yafs3 / script
            if not source.exists():
                print(f"{script:<46} (not in this checkout)")
                continue
            folders = {}
            for side in ("yafs3", "ours"):
                folder = Path(tmp) / script.replace("/", "_") / side
                shutil.copytree(source.parent, folder, ignore=shutil.ignore_patterns("*.mp4", "*.gif", "__pycache__"))
                if side == "ours":
                    port_imports(folder)
                folders[side] = folder
            times: dict[str, list[tuple[float, float]]] = {"yafs3": [], "ours": []}
            written: dict[str, list[Path]] = {}
            for _ in range(repeats):
                for side, lib in (("yafs3", library), ("ours", REPOSITORY)):
                    seconds, csvs = run_script(folders[side], script, lib, site, cpu, timeout_s, split)
                    if seconds is not None:
                        times[side].append(seconds)
                    written.setdefault(side, csvs)
            names = {side: [p.relative_to(folders[side]) for p in written[side]] for side in written}
            if not names["yafs3"]:
                verdict = "YAFS3 wrote none"
            elif names["yafs3"] != names["ours"]:
                verdict = "different files"
            else:
                same = sum((folders["yafs3"] / n).read_bytes() == (folders["ours"] / n).read_bytes()
                           for n in names["yafs3"])
                verdict = f"{same}/{len(names['yafs3'])} identical"
            if not times["yafs3"] or not times["ours"]:
                print(f"{script:<46} {'failed':>9}  {verdict}")
                continue
            theirs = statistics.median(t for t, _ in times["yafs3"])
            ours = statistics.median(t for t, _ in times["ours"])
            core_theirs = statistics.median(t - u for t, u in times["yafs3"])
            core_ours = statistics.median(t - u for t, u in times["ours"])
            pairs = [a[0] / b[0] for a, b in zip(times["yafs3"], times["ours"], strict=False) if b[0] > 0]
            script_ours = statistics.median(u for _, u in times["ours"])
            ceiling = f"{theirs / script_ours:7.2f}x" if script_ours > 0 else f"{'none':>8}"
            core = (f"{core_theirs:10.3f} {core_ours:9.3f} {core_theirs / core_ours:6.2f}x {ceiling}  "
                    if split else "")
            print(f"{script:<46} {theirs:9.3f} {ours:9.3f} {theirs / ours:6.2f}x "
                  f"{statistics.median(pairs):7.2f}x {core}{verdict}", flush=True)
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--requests", type=int, default=20_000, help="requests to simulate (synthetic)")
    parser.add_argument("--yafs3", type=Path, help="a YAFS3 checkout: compare with it on its own scripts")
    parser.add_argument("--scripts", nargs="*", help="subset of the YAFS3 scripts (substrings of their paths)")
    parser.add_argument("--repeats", type=int, default=5, help="alternating runs per library and script")
    parser.add_argument("--cpu", action="store_true", help="time Sim.run in CPU seconds instead of wall")
    parser.add_argument("--split", action="store_true",
                        help="also time the scripts' own code called from Sim.run (columns 'core')")
    parser.add_argument("--timeout", type=float, default=1800, help="seconds allowed per script run")
    args = parser.parse_args(argv)
    if args.yafs3 is not None:
        scripts = [s for s in YAFS3_SCRIPTS if not args.scripts or any(k in s for k in args.scripts)]
        return compare_with_yafs3(args.yafs3.resolve(), scripts, args.repeats, args.cpu, args.timeout,
                                  args.split)
    print(f"Python {sys.version.split()[0]}; {args.requests} requests x {len(SERVERS)} copies")
    with tempfile.TemporaryDirectory() as tmp:
        measure("yafs3 engine+results", args.requests, Path(tmp))
        measure("concurrent+results", args.requests, Path(tmp), ConcurrentService())
        measure("concurrent, no results", args.requests, None, ConcurrentService())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
