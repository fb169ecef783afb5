//! `facesynth augment` and `evaluate`: gallery augmentation and recognition (paper section 3
//! and 4) on the command line.

use super::EvaluateArgs;
use crate::io;
use anyhow::Result;
use serde_json::json;
use std::path::Path;

/// `facesynth evaluate`: the recognition report as JSON.
pub fn evaluate(args: &EvaluateArgs) -> Result<serde_json::Value> {
    use crate::recognition::ProtocolParams;
    let list = |s: &str| -> Vec<String> {
        s.split(',')
            .map(str::trim)
            .filter(|x| !x.is_empty())
            .map(String::from)
            .collect()
    };
    let params = ProtocolParams {
        metric: args.metric,
        pose: args.pose,
        pose_points: args.pose_points,
        gallery_scans: list(&args.gallery_scans),
        probe_scans: list(&args.probe_scans),
        fisher: crate::recognition::FisherParams {
            max_pca_dims: args.pca_dims,
            within_class_regularisation: args.sw_floor,
            ..Default::default()
        },
        expression_training: args.expression_training.clone(),
        landmarks_dir: args.landmarks_dir.clone(),
        expression_weights: (!args.no_expression_weights).then_some(
            crate::recognition::ExpressionWeightParams {
                scale_mm: args.expression_weight_mm,
            },
        ),
        ..ProtocolParams::default()
    };
    if let Some(w) = &params.expression_weights {
        w.validate()?;
    }
    if let (Some(dir), None) = (&args.expression_training, &args.augmented) {
        return Err(crate::Error::invalid(
            dir,
            "--expression-training needs --augmented: the learned deviations enter the \
             within-class scatter, which a gallery of one scan per person does not have",
        )
        .into());
    }
    let samples = crate::recognition::protocol::collect_samples(
        &args.dataset,
        args.augmented.as_deref(),
        &params,
    )?;
    let in_dataset = |e: crate::Error| e.in_file(&args.dataset);
    // With learned deviations, the FEM expressions alone too (`synthetic_only`), from the
    // same PCA.
    let learned_too: &[bool] = if samples.deviations.is_empty() {
        &[true]
    } else {
        &[true, false]
    };
    let mut evals =
        crate::recognition::protocol::score_variants(&samples, true, learned_too, &params)
            .map_err(in_dataset)?;
    let synthetic_only = (evals.len() > 1).then(|| evals.remove(1));
    let eval = evals.remove(0);
    let mut value = serde_json::to_value(&eval.report)?;
    // With synthetic expressions, also the same probes against the plain neutral gallery.
    let without = match args.augmented {
        Some(_) => Some(
            crate::recognition::protocol::score(&samples, false, &params).map_err(in_dataset)?,
        ),
        None => None,
    };
    let summary = |r: &crate::recognition::Report| {
        json!({
            "method": r.method, "method_note": r.method_note,
            "rank1": r.rank1, "rank5": r.rank5, "cmc": r.cmc,
            "by_probe_kind": r.by_probe_kind, "gallery_samples": r.gallery_samples,
        })
    };
    if let Some(w) = &without {
        value["without_augmentation"] = summary(&w.report);
    }
    if let Some(r) = &synthetic_only {
        value["synthetic_only"] = summary(&r.report);
    }
    if let Some(path) = &args.plot {
        let curves = cmc_curves(&eval.report, without.as_ref().map(|w| &w.report));
        let title = format!(
            "CMC, {} subjects, {} probes ({:?}, pose {:?})",
            eval.report.subjects, eval.report.probes, params.metric, params.pose
        )
        .to_lowercase()
        .replacen("cmc", "CMC", 1);
        crate::recognition::plot::write_cmc_png(
            path,
            &title,
            &curves,
            crate::recognition::plot::DEFAULT_SIZE,
        )?;
    }
    if let Some(path) = &args.report {
        io::write_text_atomic(path, &(serde_json::to_string_pretty(&value)? + "\n"))?;
    }
    if let Some(path) = &args.features {
        io::write_text_atomic(path, &serde_json::to_string(&eval.features_json())?)?;
    }
    Ok(value)
}

/// The curves of `evaluate --plot`: all probes (bold) and each probe kind, solid for the
/// run scored (`with`: augmented when there are synthetic samples), dashed for `without`.
fn cmc_curves(
    with: &crate::recognition::Report,
    without: Option<&crate::recognition::Report>,
) -> Vec<crate::recognition::plot::Curve> {
    use crate::recognition::plot::Curve;
    let augmented = with.synthetic_gallery_samples > 0;
    let with_tag = if with.learned_deviations > 0 {
        format!(
            ", with aug. + learned ({} people)",
            with.expression_training_subjects
        )
    } else {
        ", with aug.".to_string()
    };
    let mut out = Vec::new();
    let mut add = |report: &crate::recognition::Report, tag: &str, dashed: bool| {
        out.push(Curve {
            label: format!(
                "all {} probes{tag}: rank-1 {:.1} %",
                report.probes,
                100.0 * report.rank1
            ),
            cmc: report.cmc.clone(),
            colour: 0,
            dashed,
            bold: true,
        });
        for (k, (kind, rates)) in report.by_probe_kind.iter().enumerate() {
            out.push(Curve {
                label: format!(
                    "{kind} ({}){tag}: {:.1} %",
                    rates.probes,
                    100.0 * rates.rank1
                ),
                cmc: rates.cmc.clone(),
                colour: k + 1,
                dashed,
                bold: false,
            });
        }
    };
    match without {
        Some(w) => {
            add(w, ", without aug.", true);
            add(with, &with_tag, false);
        }
        None => add(with, if augmented { &with_tag } else { "" }, false),
    }
    out
}

/// `facesynth augment`: the batch with a progress line per scan on stderr.
pub fn augment(
    gallery: &Path,
    out: &Path,
    params: &crate::augment::AugmentParams,
) -> Result<serde_json::Value> {
    let start = std::time::Instant::now();
    // A bar on a terminal; one line per scan where stderr is a log (indicatif hides the bar
    // there). Failures are printed above the bar so they stay on screen.
    let bar = indicatif::ProgressBar::new(0).with_style(
        indicatif::ProgressStyle::with_template(
            "augment {bar:30} {pos}/{len} scans, {elapsed} elapsed, eta {eta}  {wide_msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let result = crate::augment::augment(gallery, out, params, &|k, n, line| {
        if bar.is_hidden() {
            eprintln!("augment [{k}/{n}] {line}");
            return;
        }
        if k == 0 {
            bar.set_length(n as u64);
            // Elapsed and eta keep moving while the first (slow) scans run.
            bar.enable_steady_tick(std::time::Duration::from_millis(250));
        }
        bar.set_position(k as u64);
        if line.contains("FAILED") {
            bar.println(format!("augment [{k}/{n}] {line}"));
        }
        bar.set_message(line.to_string());
    });
    bar.finish_and_clear();
    let (done, failed) = result?;
    let seconds = start.elapsed().as_secs_f64();
    Ok(json!({
        "gallery": gallery, "out": out,
        "scans": done.len() + failed.len(),
        "augmented": done.iter().filter(|a| !a.resumed).count(),
        "resumed": done.iter().filter(|a| a.resumed).count(),
        "redone_with_new_settings": done.iter().filter(|a| a.redone).count(),
        "failures": failed,
        "shard": params.shard.map(|s| format!("{}/{}", s.index, s.count)),
        // Scans augmented from a correction file's points rather than detected ones.
        "corrected_landmarks": done
            .iter()
            .filter(|a| a.landmarks_source != crate::pipeline::LandmarkSource::Detected)
            .map(|a| json!({
                "scan": a.scan, "source": a.landmarks_source, "corrected": a.corrected_points,
            }))
            .collect::<Vec<_>>(),
        "expressions_per_scan": done.iter().map(|a| a.expressions).max().unwrap_or(0),
        "seconds": seconds,
    }))
}
