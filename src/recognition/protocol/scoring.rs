//! Scoring: Fisherfaces trained on the gallery, every probe ranked, the CMC and the report.

use super::*;

/// Runs the protocol on `dataset`, with the synthetic gallery expressions of `augmented` if
/// given.
pub fn evaluate(
    dataset: &Path,
    augmented: Option<&Path>,
    params: &ProtocolParams,
) -> Result<Evaluation> {
    let samples = collect_samples(dataset, augmented, params)?;
    score(&samples, true, params).map_err(|e| e.in_file(dataset))
}

/// Trains on the gallery (with the synthetic expressions and the learned deviations when
/// `with_synthetic`) and matches the probes.
pub fn score(
    samples: &Samples,
    with_synthetic: bool,
    params: &ProtocolParams,
) -> Result<Evaluation> {
    let mut evals = score_variants(samples, with_synthetic, &[with_synthetic], params)?;
    Ok(evals.remove(0))
}

/// One [`score`] per entry of `with_learned` (the learned deviations on or off; `evaluate`'s
/// `synthetic_only` figure has them off), on the same gallery: the models share their PCA
/// ([`FisherModel::train_variants`]), which is most of the training time.
pub fn score_variants(
    samples: &Samples,
    with_synthetic: bool,
    with_learned: &[bool],
    params: &ProtocolParams,
) -> Result<Vec<Evaluation>> {
    let t0 = Instant::now();
    let failures = &samples.failures;
    let mut gallery = samples.gallery.clone();
    if with_synthetic {
        gallery.extend(samples.synthetic.iter().cloned());
    }
    let mut identities: Vec<String> = gallery.iter().map(|s| s.subject.clone()).collect();
    identities.sort();
    identities.dedup();
    if identities.len() < 2 {
        return Err(Error::algorithm(
            "evaluate",
            format!(
                "{} gallery identities; need at least 2 ({} scans failed{})",
                identities.len(),
                failures.len(),
                failures
                    .first()
                    .map(|f| format!(", first: {}", f.reason))
                    .unwrap_or_default()
            ),
        ));
    }
    let id_of = |s: &str| identities.binary_search_by(|x| x.as_str().cmp(s)).ok();
    let labels: Vec<usize> = gallery.iter().map(|s| id_of(&s.subject).unwrap()).collect();
    let t1 = Instant::now();
    // Expression weights: only a gallery with synthetic expressions has them.
    let weights = match (&params.expression_weights, with_synthetic) {
        (Some(w), true) => {
            expression_weights(&samples.gallery, &samples.synthetic, &params.range, w)?
        }
        _ => None,
    };
    if let Some(w) = &weights {
        for s in gallery.iter_mut() {
            apply_weights(w, &mut s.features);
        }
    }
    let deviations: Cow<[Vec<f64>]> = match &weights {
        Some(w) => Cow::Owned(samples.deviations.iter().map(|d| weighted(w, d)).collect()),
        None => Cow::Borrowed(&samples.deviations),
    };
    // The probes once for all variants, weighted like the gallery.
    let probes: Cow<[Sample]> = match &weights {
        Some(w) => Cow::Owned(
            samples
                .probes
                .iter()
                .map(|p| Sample {
                    features: weighted(w, &p.features),
                    ..p.clone()
                })
                .collect(),
        ),
        None => Cow::Borrowed(&samples.probes),
    };
    let weighting = weights
        .as_deref()
        .zip(params.expression_weights.as_ref())
        .map(|(w, p)| WeightSummary::new(w, p, &params.range));
    let xs: Vec<&[f64]> = gallery.iter().map(|s| s.features.as_slice()).collect();
    let sets: Vec<&[Vec<f64>]> = with_learned
        .iter()
        .map(|&learned| -> &[Vec<f64>] {
            if with_synthetic && learned {
                &deviations
            } else {
                &[]
            }
        })
        .collect();
    let models = FisherModel::train_variants(&xs, &labels, &sets, &params.fisher)?;
    let t_train = t1.elapsed().as_secs_f64();
    models
        .into_iter()
        .zip(sets)
        .map(|(model, deviations)| {
            let learned = if model.method == Method::Fisherfaces {
                deviations.len()
            } else {
                0
            };
            rank_probes(
                samples,
                &model,
                learned,
                Matching {
                    gallery: &gallery,
                    labels: &labels,
                    identities: &identities,
                    probes: &probes,
                    weighting,
                },
                failures.clone(),
                (t0, t_train),
                params,
            )
        })
        .collect()
}

/// The expression weights a run used, as the report gives them.
#[derive(Debug, Clone, Copy)]
struct WeightSummary {
    scale_mm: f64,
    /// Smallest and mean weight inside the elliptic mask.
    min: f64,
    mean: f64,
}

impl WeightSummary {
    fn new(w: &[f64], params: &ExpressionWeightParams, range: &RangeImageParams) -> Self {
        let (mut min, mut sum, mut n) = (1.0f64, 0.0, 0usize);
        for (x, _) in w.iter().zip(range.mask()).filter(|(_, m)| *m) {
            min = min.min(*x);
            sum += x;
            n += 1;
        }
        WeightSummary {
            scale_mm: params.scale_mm,
            min,
            mean: sum / n.max(1) as f64,
        }
    }
}

/// What one model is matched with: the gallery it was trained on and the probes, both weighted
/// when `weighting` is set.
struct Matching<'a> {
    gallery: &'a [Sample],
    /// Identity index of every gallery sample.
    labels: &'a [usize],
    identities: &'a [String],
    probes: &'a [Sample],
    weighting: Option<WeightSummary>,
}

/// Projects the gallery and the probes with `model` and ranks every probe (one variant of
/// [`score_variants`]).
fn rank_probes(
    samples: &Samples,
    model: &FisherModel,
    learned: usize,
    matching: Matching,
    failures: Vec<Failure>,
    (t0, t_train): (Instant, f64),
    params: &ProtocolParams,
) -> Result<Evaluation> {
    let Matching {
        gallery,
        labels,
        identities,
        probes,
        weighting,
    } = matching;
    let t_images = samples.seconds;
    let id_of = |s: &str| identities.binary_search_by(|x| x.as_str().cmp(s)).ok();
    let t2 = Instant::now();
    let gproj: Vec<Vec<f64>> = gallery
        .par_iter()
        .map(|s| model.project(&s.features))
        .collect();
    let n = identities.len();
    let mut ranks = Vec::new();
    let mut best = Vec::new();
    let mut kinds = Vec::new();
    let mut matched = Vec::new();
    let mut without_gallery = Vec::new();
    for p in probes {
        // Nothing failed: the person is not in the gallery, so the probe cannot be ranked.
        let Some(truth) = id_of(&p.subject) else {
            without_gallery.push(p.path.clone());
            continue;
        };
        let proj = model.project(&p.features);
        let mut dist = vec![f64::INFINITY; n];
        for (g, &l) in gproj.iter().zip(labels) {
            dist[l] = dist[l].min(params.metric.distance(g, &proj));
        }
        ranks.push(rank_of(&dist, truth));
        let b = (0..n).min_by(|&i, &j| dist[i].total_cmp(&dist[j])).unwrap();
        best.push(identities[b].clone());
        kinds.push((p.kind.clone(), *ranks.last().unwrap()));
        matched.push(p);
    }
    let t_match = t2.elapsed().as_secs_f64();
    let (all, by_probe_kind) = rates_by_kind(&kinds, n);
    let method_note = match model.method {
        Method::Fisherfaces => format!(
            "Fisherfaces: PCA to M - c = {} dims, LDA to c - 1 = {}{}",
            model.pca_dims,
            model.dims(),
            weighting.map_or(String::new(), |w| format!(
                "; samples weighted by the synthetic expressions' spread (scale {} mm)",
                w.scale_mm
            ))
        ),
        Method::Eigenfaces => format!(
            "Eigenfaces (PCA to {} dims): one gallery sample per subject, so S_w = 0 and LDA is undefined",
            model.pca_dims
        ),
    };
    let synthetic = gallery.iter().filter(|s| s.kind == "synthetic").count();
    let mut seconds = BTreeMap::new();
    seconds.insert("range_images".to_string(), t_images);
    for (k, v) in &samples.stage_seconds {
        seconds.insert(format!("range_images.{k}"), *v);
    }
    seconds.insert("train".to_string(), t_train);
    seconds.insert("match".to_string(), t_match);
    seconds.insert("total".to_string(), t_images + t0.elapsed().as_secs_f64());
    let per_probe = matched
        .iter()
        .zip(&ranks)
        .zip(&best)
        .map(|((p, &rank), b)| ProbeResult {
            file: p.path.clone(),
            subject: p.subject.clone(),
            kind: p.kind.clone(),
            rank,
            best_match: b.clone(),
        })
        .collect();
    let report = Report {
        subjects: n,
        probes: matched.len(),
        method: model.method,
        method_note,
        metric: params.metric,
        pose: params.pose,
        pose_points: params.pose_points,
        cached_landmarks: samples.cached_landmarks,
        corrected_landmarks: samples.corrected_landmarks.clone(),
        augment_failures: samples.augment_failures.clone(),
        probes_without_gallery: without_gallery,
        rank1: all.rank1,
        rank5: all.rank5,
        cmc: all.cmc,
        by_probe_kind,
        failures,
        suspect: samples.suspect.clone(),
        poses: samples.poses.clone(),
        per_probe,
        gallery_samples: gallery.len(),
        synthetic_gallery_samples: synthetic,
        learned_deviations: learned,
        expression_training_subjects: if learned > 0 {
            samples.training_subjects.len()
        } else {
            0
        },
        expression_weight_scale_mm: weighting.map(|w| w.scale_mm),
        expression_weight_min: weighting.map(|w| w.min),
        expression_weight_mean: weighting.map(|w| w.mean),
        gallery_scans: params.gallery_scans.clone(),
        pca_dims: model.pca_dims,
        projected_dims: model.dims(),
        feature_length: params.range.len(),
        range_image: params.range,
        seconds,
    };
    Ok(Evaluation {
        report,
        gallery: gallery.to_vec(),
        probes: matched.into_iter().cloned().collect(),
        identities: identities.to_vec(),
        ranks,
        best,
    })
}
