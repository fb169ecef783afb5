#!/usr/bin/env python3
"""Cross-check of facesynth's FEM export (legacy ASCII VTK, hex8) against scikit-fem.

Usage:
    facesynth export-fem --expression happiness --vtk /tmp/happy.vtk   # generic face, or add SCAN
    python3 scripts/skfem_crosscheck.py /tmp/happy.vtk                  # whole model, ~75 s
    python3 scripts/skfem_crosscheck.py --element                      # one distorted hex8
Needs numpy, scipy and scikit-fem (pip install scikit-fem). The `--element` figures are the
reference values of src/fem/hex8.rs's test `stiffness_matches_scikit_fem_with_the_same_gauss_rule`.

Units as in the Rust code (src/fem/hex8.rs): lengths mm, forces N, E converted Pa -> N/mm^2
(MPa) by 1e-6, so K is in N/mm and u in mm.

Solves the same Dirichlet problem four ways and compares each with the exported
`displacement` (and `reaction`):
  A. scikit-fem, default quadrature (intorder = 2*maxdeg = 6 -> 4x4x4 Gauss, 64 points)
  B. scikit-fem, intorder=3 (-> 2x2x2 Gauss, the Rust rule)
  C. numpy re-implementation of hex8.rs (2x2x2 Gauss), assembled with scipy
  D. scikit-fem with the VTK connectivity passed *without* the VTK->skfem node permutation
     (a wrong-node-order experiment; only the element matrices are compared, the solve is
      shown too for scale)
"""
import sys
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import skfem
from skfem import (MeshHex1, ElementHex1, ElementHex0, ElementVector, Basis,
                   BilinearForm, asm, condense, solve)
from skfem.helpers import ddot, sym_grad, trace, eye

PA_TO_N_PER_MM2 = 1e-6

# skfem's own hex8 node order (MeshHex1.doflocs on the unit cube) and VTK_HEXAHEDRON's.
SKFEM_REF = np.array([[0, 0, 0], [0, 0, 1], [0, 1, 0], [1, 0, 0],
                      [0, 1, 1], [1, 0, 1], [1, 1, 0], [1, 1, 1]], float)
VTK_REF = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                    [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
# skfem local node j is VTK local node VTK_OF_SKFEM[j]  (== skfem.io.meshio.INV_HEX_MAPPING[:8])
VTK_OF_SKFEM = np.array([int(np.where((VTK_REF == r).all(1))[0][0]) for r in SKFEM_REF])


# ----------------------------------------------------------------------------------------------
# VTK reader (legacy ASCII, exactly the layout src/fem/vtk.rs writes)
# ----------------------------------------------------------------------------------------------
def read_vtk(path):
    with open(path) as fh:
        lines = fh.read().split("\n")
    i = 0
    out = {"point": {}, "cell": {}}
    section = None
    while i < len(lines):
        ln = lines[i].strip()
        i += 1
        if not ln:
            continue
        tok = ln.split()
        if tok[0] == "POINTS":
            n = int(tok[1])
            out["points"] = np.array([[float(x) for x in lines[i + k].split()] for k in range(n)])
            i += n
        elif tok[0] == "CELLS":
            m = int(tok[1])
            rows = [[int(x) for x in lines[i + k].split()] for k in range(m)]
            assert all(r[0] == 8 for r in rows)
            out["cells"] = np.array([r[1:] for r in rows], dtype=np.int64)
            i += m
        elif tok[0] == "CELL_TYPES":
            m = int(tok[1])
            types = {int(lines[i + k]) for k in range(m)}
            assert types == {12}, types
            i += m
        elif tok[0] == "POINT_DATA":
            section, count = "point", int(tok[1])
        elif tok[0] == "CELL_DATA":
            section, count = "cell", int(tok[1])
        elif tok[0] == "VECTORS":
            out[section][tok[1]] = np.array(
                [[float(x) for x in lines[i + k].split()] for k in range(count)])
            i += count
        elif tok[0] == "SCALARS":
            assert lines[i].startswith("LOOKUP_TABLE")
            i += 1
            out[section][tok[1]] = np.array([float(lines[i + k]) for k in range(count)])
            i += count
    return out


# ----------------------------------------------------------------------------------------------
# hex8.rs in numpy (vectorised over elements)
# ----------------------------------------------------------------------------------------------
NODE_XI = 2.0 * VTK_REF - 1.0  # hex8.rs NODE_XI


def d_matrix(E_pa, nu):
    e = E_pa * PA_TO_N_PER_MM2
    lam = e * nu / ((1 + nu) * (1 - 2 * nu))
    mu = e / (2 * (1 + nu))
    D = np.zeros(np.shape(e) + (6, 6))
    D[..., :3, :3] = lam[..., None, None] if np.ndim(e) else lam
    for k in range(3):
        D[..., k, k] = lam + 2 * mu
        D[..., k + 3, k + 3] = mu
    return D


def rust_element_stiffness(X, E_pa, nu, gauss_n=2):
    """X: (m, 8, 3) nodes in VTK order, mm.  Returns (m, 24, 24), DOF 3*a+axis, N/mm."""
    X = np.asarray(X, float)
    m = X.shape[0]
    D = d_matrix(np.asarray(E_pa, float) * np.ones(m), np.asarray(nu, float) * np.ones(m))
    g, w = np.polynomial.legendre.leggauss(gauss_n)
    K = np.zeros((m, 24, 24))
    for i1, a in enumerate(g):
        for i2, b in enumerate(g):
            for i3, c in enumerate(g):
                xi = np.array([a, b, c])
                f = 1.0 + NODE_XI * xi  # (8,3)
                dN = 0.125 * np.stack([NODE_XI[:, 0] * f[:, 1] * f[:, 2],
                                       f[:, 0] * NODE_XI[:, 1] * f[:, 2],
                                       f[:, 0] * f[:, 1] * NODE_XI[:, 2]], 1)  # (8,3) dN_a/dxi_j
                J = np.einsum("mai,aj->mij", X, dN)  # J_ij = dx_i/dxi_j
                det = np.linalg.det(J)
                assert (det > 0).all(), "inverted element"
                G = np.einsum("aj,mji->mai", dN, np.linalg.inv(J))  # grad_x N_a = J^-T dN_a
                B = np.zeros((m, 6, 24))
                for k in range(8):
                    gx, gy, gz = G[:, k, 0], G[:, k, 1], G[:, k, 2]
                    c0 = 3 * k
                    B[:, 0, c0] = gx
                    B[:, 1, c0 + 1] = gy
                    B[:, 2, c0 + 2] = gz
                    B[:, 3, c0] = gy
                    B[:, 3, c0 + 1] = gx
                    B[:, 4, c0 + 1] = gz
                    B[:, 4, c0 + 2] = gy
                    B[:, 5, c0] = gz
                    B[:, 5, c0 + 2] = gx
                wt = w[i1] * w[i2] * w[i3]
                K += np.einsum("mpi,mpq,mqj->mij", B, D, B) * (det * wt)[:, None, None]
    return 0.5 * (K + K.transpose(0, 2, 1))


def assemble_rust(points, cells, E, nu, gauss_n=2):
    """Global K of hex8.rs's element formula, gauss_n points per axis (hex8.rs uses 2)."""
    Ke = rust_element_stiffness(points[cells], E, nu, gauss_n=gauss_n)
    dofs = (3 * cells[:, :, None] + np.arange(3)).reshape(len(cells), 24)
    rows = np.repeat(dofs, 24, axis=1).ravel()
    cols = np.tile(dofs, (1, 24)).ravel()
    n = 3 * len(points)
    return sp.coo_matrix((Ke.ravel(), (rows, cols)), shape=(n, n)).tocsr()


# ----------------------------------------------------------------------------------------------
# scikit-fem
# ----------------------------------------------------------------------------------------------
@BilinearForm
def elasticity_varcoef(u, v, w):
    eps_u, eps_v = sym_grad(u), sym_grad(v)
    sig = 2.0 * w["mu"] * eps_u + w["lam"] * eye(trace(eps_u), 3)
    return ddot(sig, eps_v)


def skfem_stiffness(points, cells_skfem_order, E, nu, intorder=None):
    """Global K in the interleaved numbering 3*node+axis (remapped from skfem's dofs)."""
    mesh = MeshHex1(np.ascontiguousarray(points.T), np.ascontiguousarray(cells_skfem_order.T))
    kw = {} if intorder is None else {"intorder": intorder}
    basis = Basis(mesh, ElementVector(ElementHex1()), **kw)
    basis0 = basis.with_element(ElementHex0())
    e = E * PA_TO_N_PER_MM2
    lam = e * nu / ((1 + nu) * (1 - 2 * nu))
    mu = e / (2 * (1 + nu))
    K = asm(elasticity_varcoef, basis, lam=basis0.interpolate(lam), mu=basis0.interpolate(mu))
    # skfem dof of (node i, component c) -> 3*i+c
    nd = basis.nodal_dofs  # (3, nnodes)
    perm = np.empty(3 * len(points), dtype=np.int64)
    for c in range(3):
        perm[3 * np.arange(len(points)) + c] = nd[c]
    K = K.tocsr()[perm][:, perm]
    return K.tocsr(), basis


# ----------------------------------------------------------------------------------------------
def solve_dirichlet(K, f, fixed_dof, u_fixed):
    """K u = f on the free DOFs with u = u_fixed on fixed DOFs (direct, SuperLU)."""
    n = K.shape[0]
    free = np.setdiff1d(np.arange(n), fixed_dof)
    u = np.zeros(n)
    u[fixed_dof] = u_fixed
    Kff = K[free][:, free].tocsc()
    rhs = f[free] - K[free][:, fixed_dof] @ u_fixed
    u[free] = spla.spsolve(Kff, rhs)
    return u


def rel(a, b):
    d = a - b
    return np.abs(d).max() / np.abs(b).max(), np.linalg.norm(d) / np.linalg.norm(b)


def report(name, u, K, f, ref_u, ref_r, fixed_dof):
    r = K @ u - f
    r_fixed = np.zeros_like(r)
    r_fixed[fixed_dof] = r[fixed_dof]
    mu_, nu_ = rel(u, ref_u)
    mr, nr = rel(r_fixed, ref_r)
    print(f"  {name:52s} u: max {mu_:.3e}  2n {nu_:.3e} | reaction: max {mr:.3e}  2n {nr:.3e}")
    return mu_, nu_, mr, nr


def one_element():
    """The distorted element of hex8.rs's tests: hex8.rs in numpy against scikit-fem with the
    2x2x2 rule (intorder=3) and its default (4x4x4)."""
    X = VTK_REF * [4.0, 3.0, 2.0]
    X[6] += [0.7, 0.4, 0.3]
    X[1] += [0.2, -0.3, 0.1]
    X[4] += [-0.2, 0.1, 0.25]
    E, nu = np.array([5600.0]), np.array([0.45])
    K2 = rust_element_stiffness(X[None], E, nu, 2)[0]
    K4 = rust_element_stiffness(X[None], E, nu, 4)[0]
    K8 = rust_element_stiffness(X[None], E, nu, 8)[0]

    def sk(intorder):
        K, _ = skfem_stiffness(X, VTK_OF_SKFEM[None, :], E, nu, intorder)
        return K.toarray()

    S3, S6 = sk(3), sk(None)
    s = np.abs(K2).max()
    print("max|K| =", repr(s))
    print("skfem intorder=3 vs hex8.rs 2x2x2 :", np.abs(S3 - K2).max() / s)
    print("skfem default    vs hex8.rs 4x4x4 :", np.abs(S6 - K4).max() / s)
    print("2x2x2 vs 4x4x4 (hex8.rs formula)  :", np.abs(K2 - K4).max() / s)
    print("4x4x4 vs 8x8x8                    :", np.abs(K4 - K8).max() / s)
    for (i, j) in [(0, 0), (0, 1), (2, 2), (18, 18), (18, 19), (3, 20), (5, 12), (23, 0)]:
        print(f"K[{i:2d},{j:2d}]  skfem(intorder=3) {S3[i, j]!r:>24}  skfem default {S6[i, j]!r:>24}")
    print("trace skfem(intorder=3)", repr(np.trace(S3)), " skfem default", repr(np.trace(S6)))


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--element":
        return one_element()
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    path = sys.argv[1]
    t0 = time.time()
    v = read_vtk(path)
    P, C = v["points"], v["cells"]
    U = v["point"]["displacement"].ravel()
    F = v["point"]["force"].ravel()
    R = v["point"]["reaction"].ravel()
    fixed = v["point"]["fixed"].astype(bool)
    E, NU = v["cell"]["young_modulus_pa"], v["cell"]["poisson_ratio"]
    print(f"scikit-fem {skfem.__version__}, {len(P)} points, {len(C)} hex8, "
          f"{fixed.sum()} fixed nodes ({(np.abs(v['point']['displacement'][fixed]).max(1) > 0).sum()}"
          f" with non-zero prescribed motion), free dofs {3 * (~fixed).sum()}")
    print("  materials (E Pa, nu):", sorted({(a, b) for a, b in zip(E, NU)}),
          f" unused nodes: {len(P) - len(np.unique(C))}")
    print(f"  force on fixed nodes (ignored by both solvers): "
          f"max |f| = {np.abs(v['point']['force'][fixed]).max():.3e} N")
    fixed_dof = (3 * np.nonzero(fixed)[0][:, None] + np.arange(3)).ravel()
    u_fixed = U[fixed_dof]

    # --- C: numpy hex8.rs ----------------------------------------------------------------------
    K_rust = assemble_rust(P, C, E, NU)
    free = np.setdiff1d(np.arange(3 * len(P)), fixed_dof)
    res = (K_rust @ U - F)[free]
    print(f"  residual of the exported u in the numpy-hex8.rs matrix: max|K u - f|_free = "
          f"{np.abs(res).max():.3e} N (max |f| {np.abs(F).max():.3e} N)")

    # --- the skfem matrices --------------------------------------------------------------------
    cells_sk = C[:, VTK_OF_SKFEM]
    K_sk6, _ = skfem_stiffness(P, cells_sk, E, NU)              # default: intorder 6
    K_sk3, basis3 = skfem_stiffness(P, cells_sk, E, NU, intorder=3)
    K_bad, _ = skfem_stiffness(P, C, E, NU, intorder=3)          # no permutation (wrong)
    nq_default = Basis(basis3.mesh, ElementVector(ElementHex1())).X.shape[1]
    print(f"  skfem quadrature points per element: default {nq_default}, intorder=3 "
          f"{basis3.X.shape[1]} (1D points {np.unique(basis3.X[0]).round(12)})")

    def mdiff(A, B):
        d = (A - B).tocoo()
        return np.abs(d.data).max() / np.abs(B.data).max() if d.nnz else 0.0

    print("  global stiffness, max |dK| / max |K_rust|:")
    print(f"    skfem default quadrature (4x4x4)  vs hex8.rs: {mdiff(K_sk6, K_rust):.3e}")
    print(f"    skfem intorder=3 (2x2x2)          vs hex8.rs: {mdiff(K_sk3, K_rust):.3e}")
    print(f"    skfem, VTK order unpermuted       vs hex8.rs: {mdiff(K_bad, K_rust):.3e}")
    K_r4 = assemble_rust(P, C, E, NU, gauss_n=4)
    print(f"    hex8.rs formula with 4x4x4 Gauss  vs skfem default: {mdiff(K_r4, K_sk6):.3e}")

    # --- solves --------------------------------------------------------------------------------
    print("relative difference to the exported displacement / reaction "
          "(max: max|du|/max|u|, 2n: ||du||/||u||):")
    out = {}
    for name, K in [("A skfem default quadrature (4x4x4 Gauss)", K_sk6),
                    ("B skfem intorder=3 (2x2x2 Gauss, = hex8.rs)", K_sk3),
                    ("C numpy hex8.rs + scipy spsolve", K_rust),
                    ("E numpy hex8.rs formula, 4x4x4 Gauss", K_r4),
                    ("D skfem, VTK node order NOT permuted", K_bad)]:
        u = solve_dirichlet(K, F, fixed_dof, u_fixed)
        out[name] = report(name, u, K, F, U, R, fixed_dof)
    print(f"done in {time.time() - t0:.1f} s")
    return out


if __name__ == "__main__":
    main()
