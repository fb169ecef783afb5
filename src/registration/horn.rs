//! Step 1, global alignment: Horn's closed-form absolute orientation with unit quaternions.

use super::*;

/// Horn (1987) closed-form absolute orientation with unit quaternions: the similarity `T`
/// minimising Σ |to_i − T(from_i)|². The rotation is the eigenvector of the largest
/// eigenvalue of Horn's symmetric 4×4 matrix N. With `with_scale` the scale is the
/// least-squares one, s = Σ to'_i · R from'_i / Σ |from'_i|² (primes: centred), which makes
/// the result the same as Umeyama's SVD solution; without it s = 1 (rigid).
///
/// Needs ≥ 3 points that are not collinear.
pub fn horn_absolute_orientation(
    from: &[DVec3],
    to: &[DVec3],
    with_scale: bool,
) -> Result<Similarity> {
    if from.len() != to.len() || from.len() < 3 {
        return Err(Error::algorithm(
            "horn",
            format!("need ≥ 3 point pairs, got {} and {}", from.len(), to.len()),
        ));
    }
    let n = from.len() as f64;
    let ca = from.iter().copied().sum::<DVec3>() / n;
    let cb = to.iter().copied().sum::<DVec3>() / n;
    let mut s = [[0.0f64; 3]; 3]; // s[i][j] = Σ a'_i b'_j
    let mut aa = 0.0;
    for (a, b) in from.iter().zip(to) {
        let a = (*a - ca).to_array();
        let b = (*b - cb).to_array();
        for i in 0..3 {
            aa += a[i] * a[i];
            for j in 0..3 {
                s[i][j] += a[i] * b[j];
            }
        }
    }
    // Collinearity check: the spread of `from` must have rank ≥ 2.
    let cov = {
        let mut m = nalgebra::Matrix3::<f64>::zeros();
        for a in from {
            let d = *a - ca;
            let v = nalgebra::Vector3::new(d.x, d.y, d.z);
            m += v * v.transpose();
        }
        m
    };
    let ev = nalgebra::SymmetricEigen::new(cov).eigenvalues;
    let mut ev: Vec<f64> = ev.iter().copied().collect();
    ev.sort_by(f64::total_cmp);
    if !(ev[1] > 1e-12 * ev[2].max(1e-300)) || aa <= 0.0 {
        return Err(Error::algorithm(
            "horn",
            "the feature points are collinear or coincide",
        ));
    }
    let [[sxx, sxy, sxz], [syx, syy, syz], [szx, szy, szz]] = s;
    #[rustfmt::skip]
    let nm = nalgebra::Matrix4::new(
        sxx + syy + szz, syz - szy,       szx - sxz,        sxy - syx,
        syz - szy,       sxx - syy - szz, sxy + syx,        szx + sxz,
        szx - sxz,       sxy + syx,       -sxx + syy - szz, syz + szy,
        sxy - syx,       szx + sxz,       syz + szy,        -sxx - syy + szz,
    );
    let eig = nalgebra::SymmetricEigen::new(nm);
    let k = eig.eigenvalues.imax();
    let q = eig.eigenvectors.column(k);
    let rotation = DQuat::from_xyzw(q[1], q[2], q[3], q[0]).normalize();
    let scale = if with_scale {
        let mut num = 0.0;
        for (a, b) in from.iter().zip(to) {
            num += (*b - cb).dot(rotation * (*a - ca));
        }
        num / aa
    } else {
        1.0
    };
    if !(scale > 0.0 && scale.is_finite()) {
        return Err(Error::algorithm(
            "horn",
            format!("degenerate scale {scale}"),
        ));
    }
    Ok(Similarity {
        rotation,
        scale,
        translation_mm: cb - scale * (rotation * ca),
    })
}
