#!/usr/bin/python3
"""scikit-learn side of scripts/bench_cluster.sh: PCA (randomized) + KMeans (k-means++, n_init=1)
on the same NBTFMAT1 matrix file nbtf reads, then the full-space inertia of both label sets.

Usage: bench_cluster_sklearn.py MATRIX OUT_DIR REPEAT K [K ...]
Every stage runs REPEAT times and the fastest is reported (nbtf's side does the same).
Writes OUT_DIR/sklearn.json; reads OUT_DIR/nbtf_labels_K.i32 (written by nbtf-bench-cluster run)
to score nbtf's labels with the same code as scikit-learn's.
"""
import json
import sys
import time

import numpy as np
import sklearn
from sklearn.cluster import KMeans
from sklearn.decomposition import PCA


def read_matrix(path):
    with open(path, "rb") as f:
        if f.read(8) != b"NBTFMAT1":
            sys.exit(f"{path}: not an NBTFMAT1 matrix file")
        rows, cols = np.frombuffer(f.read(16), dtype=np.uint64)
        data = np.fromfile(f, dtype=np.float32, count=int(rows) * int(cols))
    return data.reshape(int(rows), int(cols))


def full_space_inertia(x, labels, k):
    """Sum of squared distances of the standardized ABRDFs (all D dimensions) to their
    cluster's mean: sum |x|^2 - sum_c |sum_c x|^2 / n_c, accumulated in float64."""
    total = 0.0
    sums = np.zeros((k, x.shape[1]), dtype=np.float64)
    step = 1000
    for r in range(0, x.shape[0], step):
        block = x[r:r + step].astype(np.float64)
        total += float(np.einsum("ij,ij->", block, block))
        np.add.at(sums, labels[r:r + step], block)
    counts = np.bincount(labels, minlength=k).astype(np.float64)
    nonempty = counts > 0
    return total - float((np.einsum("ij,ij->i", sums[nonempty], sums[nonempty]) / counts[nonempty]).sum())


def main():
    matrix, out, repeat, ks = sys.argv[1], sys.argv[2], int(sys.argv[3]), [int(k) for k in sys.argv[4:]]
    x = read_matrix(matrix)
    report = {"sklearn_version": sklearn.__version__, "texels": x.shape[0], "dimensions": x.shape[1]}

    seconds = []
    for _ in range(repeat):
        start = time.perf_counter()
        pca = PCA(n_components=32, svd_solver="randomized", random_state=0)
        scores = pca.fit_transform(x)
        seconds.append(time.perf_counter() - start)
    report["repeat"] = repeat
    report["pca"] = {"seconds": min(seconds),
                     "explained_variance_ratio": float(pca.explained_variance_ratio_.sum())}
    print(f"sklearn pca: {report['pca']['seconds']:.3f} s, explained {report['pca']['explained_variance_ratio']:.4f}",
          file=sys.stderr)

    report["kmeans"] = []
    for k in ks:
        seconds = []
        for _ in range(repeat):
            start = time.perf_counter()
            km = KMeans(n_clusters=k, init="k-means++", n_init=1, random_state=0).fit(scores)
            seconds.append(time.perf_counter() - start)
        seconds = min(seconds)
        entry = {"k": k, "seconds": seconds, "iterations": int(km.n_iter_), "inertia": float(km.inertia_)}
        entry["full_space_inertia"] = full_space_inertia(x, km.labels_.astype(np.int64), k)
        nbtf_labels = np.fromfile(f"{out}/nbtf_labels_{k}.i32", dtype=np.int32).astype(np.int64)
        entry["nbtf_full_space_inertia"] = full_space_inertia(x, nbtf_labels, k)
        report["kmeans"].append(entry)
        print(f"sklearn k={k}: {seconds:.3f} s ({entry['iterations']} iterations), inertia {entry['inertia']:.6g}",
              file=sys.stderr)
    with open(f"{out}/sklearn.json", "w") as f:
        json.dump(report, f, indent=2)


if __name__ == "__main__":
    main()
