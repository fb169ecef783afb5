#!/usr/bin/env python3
"""Cross-check facesynth's Fisherfaces ranking against scikit-learn on the same features.

    facesynth evaluate --dataset DIR [--gallery-scans ...] --features /tmp/f.json
    python3 scripts/sklearn_crosscheck.py /tmp/f.json [--metric cosine|euclidean]

The features JSON holds the gallery and probe range images (f32) as the model saw them
(multiplied by the expression weights when the report's `expression_weight_scale_mm` is set),
their subjects, and facesynth's per-probe rank and best identity. This script builds the same model with
scikit-learn — PCA to M - c components then LinearDiscriminantAnalysis (paper eqs. 1-9), or
PCA to M - 1 (Eigenfaces) when every class has one sample — ranks the gallery identities for
each probe (distance to the identity = minimum over its gallery samples, ties pessimistic) and
prints how often the two agree. Not part of the tests (needs numpy and scikit-learn).
"""
import argparse
import json

import numpy as np
from sklearn.decomposition import PCA
from sklearn.discriminant_analysis import LinearDiscriminantAnalysis


def distances(g, p, metric):
    if metric == "euclidean":
        return np.sqrt(((p[:, None, :] - g[None, :, :]) ** 2).sum(-1))
    gn = g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-300)
    pn = p / np.maximum(np.linalg.norm(p, axis=1, keepdims=True), 1e-300)
    return np.maximum(1.0 - pn @ gn.T, 0.0)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("features")
    ap.add_argument("--metric", default=None, help="default: the report's metric")
    a = ap.parse_args()
    d = json.load(open(a.features))
    metric = a.metric or d["report"]["metric"]
    ids = d["identities"]
    gx = np.asarray(d["gallery"]["x"], dtype=np.float64)
    gy = np.asarray([ids.index(s) for s in d["gallery"]["subject"]])
    px = np.asarray(d["probes"]["x"], dtype=np.float64)
    py = np.asarray([ids.index(s) for s in d["probes"]["subject"]])
    m, c = len(gy), len(ids)
    if m > c:
        method = "fisherfaces"
        pca = PCA(n_components=m - c, svd_solver="full").fit(gx)
        lda = LinearDiscriminantAnalysis(solver="svd").fit(pca.transform(gx), gy)
        gp = lda.transform(pca.transform(gx))
        pp = lda.transform(pca.transform(px))
    else:
        method = "eigenfaces"
        pca = PCA(n_components=m - 1, svd_solver="full").fit(gx)
        gp, pp = pca.transform(gx), pca.transform(px)
    dist = distances(gp, pp, metric)
    per_id = np.full((len(py), c), np.inf)
    for k in range(c):
        per_id[:, k] = dist[:, gy == k].min(axis=1)
    truth = per_id[np.arange(len(py)), py]
    ranks = 1 + (per_id <= truth[:, None]).sum(1) - 1
    best = per_id.argmin(1)
    ours_rank = np.asarray(d["probes"]["rank"])
    ours_best = np.asarray([ids.index(s) for s in d["probes"]["best"]])
    kinds = d["probes"]["kind"]
    out = {
        "metric": metric,
        "method": method,
        "ours_method": d["report"]["method"],
        "probes": int(len(py)),
        "sklearn_rank1": float((ranks == 1).mean()),
        "sklearn_rank5": float((ranks <= 5).mean()),
        "ours_rank1": float((ours_rank == 1).mean()),
        "ours_rank5": float((ours_rank <= 5).mean()),
        "same_best_identity": float((best == ours_best).mean()),
        "same_rank": float((ranks == ours_rank).mean()),
        "max_rank_difference": int(np.abs(ranks - ours_rank).max()),
        "by_kind_sklearn_rank1": {
            k: float((ranks[[i for i, x in enumerate(kinds) if x == k]] == 1).mean())
            for k in sorted(set(kinds))
        },
    }
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
