//! Learned within-class deviations: other people's expression − neutral range images, added to
//! the augmented run's within-class scatter.

use super::*;

/// The scans of the expression training set `dir` that [`learned_deviations`] uses (gallery
/// and probe kinds); a set sharing a subject with `dataset_scans` is refused (a probe's own
/// expressions would be learned). Checked before any scan is read.
pub(super) fn training_scans(
    dir: &Path,
    dataset_scans: &[ScanFile],
    params: &ProtocolParams,
) -> Result<Vec<ScanFile>> {
    let scans = protocol_scans(dir, params)?;
    let mut shared: Vec<&str> = scans
        .iter()
        .filter(|t| dataset_scans.iter().any(|s| s.subject == t.subject))
        .map(|t| t.subject.as_str())
        .collect();
    shared.dedup();
    if !shared.is_empty() {
        return Err(Error::invalid(
            dir,
            format!(
                "expression training set shares {} subject(s) with the dataset ({}…): their own \
                 expressions would be learned; train on other people",
                shared.len(),
                shared[..shared.len().min(3)].join(", ")
            ),
        ));
    }
    Ok(scans)
}

/// The within-class deviations learned from the expression training `scans` (from
/// [`training_scans`], folder `dir`): for each person there with a gallery-kind scan, every
/// probe-kind scan's range image minus that gallery scan's, both posed as the evaluated scans
/// are (`reference`: the evaluated gallery's alignment reference, so the deviations live in
/// the same frame). Scans that fail are added to `failures` and skipped; scans posed despite
/// suspect feature points ([`scan_pose_checked`]) are added to `suspect`; the rotation applied
/// to each scan that gave an image is added to `poses`.
pub(super) fn learned_deviations(
    dir: &Path,
    scans: &[ScanFile],
    params: &ProtocolParams,
    generic: &GenericFace,
    reference: Option<&RangeImage>,
    (failures, suspect, poses): (
        &mut Vec<Failure>,
        &mut Vec<Failure>,
        &mut Vec<ScanOrientation>,
    ),
) -> Result<(Vec<Vec<f64>>, Vec<String>)> {
    const CONTEXT: &str = "expression training: ";
    type Posed = std::result::Result<(Sample, ScanOrientation), Failure>;
    let results: Vec<(Posed, Vec<String>)> = scans
        .par_iter()
        .map(|s| {
            let (start, reasons) = match scan_pose_checked(&s.path, params, generic, None) {
                Ok(posed) => posed,
                Err(e) => {
                    let failure = Failure {
                        file: s.path.clone(),
                        reason: format!("{CONTEXT}{e}"),
                    };
                    return (Err(failure), Vec::new());
                }
            };
            let sample = make_sample(&s.path, start, &s.subject, &s.scan, params, reference)
                .map(|(sample, frame)| (sample, ScanOrientation::of(&s.path, &frame)))
                .map_err(|f| Failure {
                    reason: format!("{CONTEXT}{}", f.reason),
                    ..f
                });
            (sample, reasons)
        })
        .collect();
    let images: Vec<Option<Sample>> = scans
        .iter()
        .zip(results)
        .map(|(s, (r, reasons))| {
            if !reasons.is_empty() {
                suspect.push(suspect_scan(&s.path, &reasons, CONTEXT));
            }
            let (sample, pose) = r.map_err(|f| failures.push(f)).ok()?;
            poses.push(pose);
            Some(sample)
        })
        .collect();
    // Each person's first gallery-kind scan that gave an image.
    let mut neutral: BTreeMap<&str, &Sample> = BTreeMap::new();
    for (s, img) in scans.iter().zip(&images) {
        if let Some(img) = img
            .as_ref()
            .filter(|_| params.gallery_scans.contains(&s.scan))
        {
            neutral.entry(s.subject.as_str()).or_insert(img);
        }
    }
    let mut deviations = Vec::new();
    let mut subjects: Vec<String> = Vec::new();
    for (s, img) in scans.iter().zip(&images) {
        let (Some(expression), Some(neutral)) = (
            img.as_ref()
                .filter(|_| params.probe_scans.contains(&s.scan)),
            neutral.get(s.subject.as_str()),
        ) else {
            continue;
        };
        deviations.push(
            expression
                .features
                .iter()
                .zip(&neutral.features)
                .map(|(e, n)| e - n)
                .collect(),
        );
        if subjects.last() != Some(&s.subject) {
            subjects.push(s.subject.clone());
        }
    }
    if deviations.is_empty() {
        return Err(Error::invalid(
            dir,
            format!(
                "no person with a {} scan and a {} scan that both gave range images",
                params.gallery_scans.join("|"),
                params.probe_scans.join("|")
            ),
        ));
    }
    Ok((deviations, subjects))
}
