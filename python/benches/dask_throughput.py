"""Throughput of wavemesh.dask on a dask.distributed LocalCluster (1 and 2 worker
processes, one thread each) beside the single-machine wavemesh.encode/decode (1 and 2
threads), on a generated int16 terrain; prints a Markdown table of median wall seconds
and Msamples/s.

    target/python-venv/bin/python python/benches/dask_throughput.py [--size 8192] [--runs 3]

The terrain is made by the workers themselves and kept in their memory (persisted), so
`to_ezw` is timed from samples in worker memory to the file on disk; `open_ezw` is timed
until every tile is decoded into worker memory (persisted, not gathered to the driver;
the file is touched before each run so that no run reuses another's tiles).
The single-machine rows time `encode(numpy array)` to bytes and `decode(path)` to a
numpy array. Every to_ezw file is checked to hold the bytes of the single-machine encode.
"""

import argparse
import os
import statistics
import tempfile
import time

import dask.array as da
import numpy as np
from dask import distributed

import wavemesh
import wavemesh.dask


def terrain(side: int, chunk: int) -> "da.Array":
    """A `side`² int16 terrain (three octaves of waves and a hashed noise) as a Dask
    array of `chunk`-sided chunks."""
    y, x = da.meshgrid(
        da.arange(side, chunks=chunk, dtype=np.float64),
        da.arange(side, chunks=chunk, dtype=np.float64),
        indexing="ij",
    )
    waves = sum(
        amplitude * da.sin(x / period + phase) * da.cos(y / (1.3 * period))
        for amplitude, period, phase in [(600, 700.0, 0.0), (150, 90.0, 1.0), (25, 11.0, 2.0)]
    )
    noise = (x.astype(np.int64) * 7919 + y.astype(np.int64) * 104729) % 7
    return (1500 + waves + noise).astype(np.int16)


def median_seconds(runs: int, work) -> float:
    """The median wall time of `runs` calls of `work()`."""
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        work()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def fresh(path: str) -> "da.Array":
    """``open_ezw(path)`` under new task names: the file is touched first, so no run
    finds the tiles another run decoded still in the workers' memory."""
    os.utime(path)
    return wavemesh.dask.open_ezw(path)


def single_machine_rows(dem: np.ndarray, path: str, runs: int) -> list:
    """Encode and decode rows of wavemesh.encode/decode with 1 and 2 threads."""
    rows = []
    for threads in (1, 2):
        seconds = median_seconds(runs, lambda: wavemesh.encode(dem, threads=threads))
        rows.append(("encode", f"wavemesh.encode, {threads} thread(s)", seconds))
    for threads in (1, 2):
        seconds = median_seconds(runs, lambda: wavemesh.decode(path, threads=threads))
        rows.append(("decode", f"wavemesh.decode, {threads} thread(s)", seconds))
    return rows


def cluster_rows(side: int, workers: int, expected: bytes, folder: str, runs: int) -> list:
    """Encode and decode rows of wavemesh.dask on a LocalCluster of `workers` processes."""
    path = os.path.join(folder, f"dask-{workers}.ezw")
    with distributed.LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, distributed.Client(cluster):
        dem = terrain(side, 1024).persist()
        distributed.wait(dem)
        encode = median_seconds(runs, lambda: wavemesh.dask.to_ezw(dem, path))
        with open(path, "rb") as f:
            assert f.read() == expected, "to_ezw's bytes differ from encode's"
        decode = median_seconds(runs, lambda: distributed.wait(fresh(path).persist()))
    label = f"wavemesh.dask, LocalCluster {workers} worker(s)"
    return [("encode", f"{label}: to_ezw", encode), ("decode", f"{label}: open_ezw", decode)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=8192, help="side of the square terrain")
    parser.add_argument("--runs", type=int, default=3, help="runs per row (median shown)")
    args = parser.parse_args()
    samples = args.size * args.size
    with tempfile.TemporaryDirectory() as folder:
        with distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster, distributed.Client(cluster):
            dem = terrain(args.size, 1024).compute()
        expected = wavemesh.encode(dem)
        reference = os.path.join(folder, "reference.ezw")
        with open(reference, "wb") as f:
            f.write(expected)
        rows = single_machine_rows(dem, reference, args.runs)
        for workers in (1, 2):
            rows += cluster_rows(args.size, workers, expected, folder, args.runs)
    print(f"{args.size} x {args.size} int16 ({samples / 1e6:.1f} Msamples), lossless, "
          f"{len(expected) / 1e6:.1f} MB, tiles of 1024, median of {args.runs} runs, "
          f"{os.cpu_count()} cores\n")
    print("| | how | wall s | Msamples/s |")
    print("|---|---|---:|---:|")
    for kind, how, seconds in sorted(rows, key=lambda r: r[0] != "encode"):
        print(f"| {kind} | {how} | {seconds:.2f} | {samples / seconds / 1e6:.1f} |")


if __name__ == "__main__":
    main()
