//! Expression presets: FACS-style descriptions mapped to muscle activations
//! (`assets/expressions.ron`, 18 presets, plus optional user files).
//!
//! An expression is `u = Σ a_i u_i` over the muscle basis, so applying one costs an
//! 18 + 8 + 4-term sum (muscles, soft-tissue loads, jaw).

use crate::{Error, FemError, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// The built-in presets (`assets/expressions.ron`).
pub const BUILTIN_RON: &str = include_str!("../../assets/expressions.ron");

/// One expression preset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Expression {
    /// snake_case name used on the command line (`happiness`, `sneer_left`, …).
    pub name: String,
    /// What it looks like.
    #[serde(default)]
    pub description: String,
    /// FACS action units it is made of ("12", "4R", …), for reference.
    #[serde(default)]
    pub action_units: Vec<String>,
    /// Muscle → activation. A pair name sets both sides, `<pair>_left` / `<pair>_right` one
    /// side (applied after the pair names).
    pub activations: BTreeMap<String, f64>,
}

/// A list of presets as stored in RON.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExpressionSet {
    pub expressions: Vec<Expression>,
}

impl Expression {
    /// The activation vector for muscles named `muscle_names` (model order). Errors on a key
    /// that names no muscle or a non-finite activation.
    pub fn activations_for(&self, muscle_names: &[String]) -> Result<Vec<f64>> {
        let mut out = vec![0.0; muscle_names.len()];
        // Pair names first, then one-sided names override.
        let mut keys: Vec<(&String, &f64)> = self.activations.iter().collect();
        keys.sort_by_key(|(k, _)| k.ends_with("_left") || k.ends_with("_right"));
        for (key, &a) in keys {
            if !a.is_finite() {
                return Err(FemError::Definition(format!(
                    "expression `{}`: activation of `{key}` is not finite",
                    self.name
                ))
                .into());
            }
            let jaw_key = crate::fem::jaw::ACTUATORS.contains(&key.as_str());
            let mut hit = false;
            for (i, name) in muscle_names.iter().enumerate() {
                // `jaw_left` / `jaw_right` are opposite shifts, not a left/right pair.
                let pair_match = !crate::fem::jaw::ACTUATORS.contains(&name.as_str())
                    && name
                        .strip_prefix(key.as_str())
                        .is_some_and(|rest| rest == "_left" || rest == "_right");
                if name == key || pair_match {
                    out[i] = a;
                    hit = true;
                }
            }
            // A model whose muscle set turns the jaw off (`jaw: None`) ignores the jaw keys.
            let ignored = jaw_key && !muscle_names.iter().any(|n| n == "jaw_open");
            if !hit && !ignored {
                return Err(FemError::Definition(format!(
                    "expression `{}`: `{key}` names no muscle",
                    self.name
                ))
                .into());
            }
        }
        Ok(out)
    }
}

impl ExpressionSet {
    /// The 18 built-in presets.
    pub fn builtin() -> Self {
        Self::parse(BUILTIN_RON, Path::new("assets/expressions.ron"))
            .expect("built-in expressions.ron parses")
    }

    /// Parses RON text (`path` only names it in errors).
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        let set: ExpressionSet = ron::from_str(text)
            .map_err(|e| Error::syntax(path, e.span.start.line, e.code.to_string()))?;
        let mut seen = std::collections::BTreeSet::new();
        for e in &set.expressions {
            if !seen.insert(e.name.as_str()) {
                return Err(Error::invalid(
                    path,
                    format!("expression `{}` twice", e.name),
                ));
            }
        }
        Ok(set)
    }

    /// Reads a user preset file (RON); its presets are added after (or replace) the built-ins
    /// with [`ExpressionSet::merge`].
    pub fn load(path: &Path) -> Result<Self> {
        Self::parse(&crate::io::read_text_file(path)?, path)
    }

    /// Adds `other`'s presets, replacing those with the same name.
    pub fn merge(&mut self, other: ExpressionSet) {
        for e in other.expressions {
            match self.expressions.iter_mut().find(|x| x.name == e.name) {
                Some(slot) => *slot = e,
                None => self.expressions.push(e),
            }
        }
    }

    /// The preset called `name`.
    pub fn get(&self, name: &str) -> Option<&Expression> {
        self.expressions.iter().find(|e| e.name == name)
    }

    /// Preset names in file order.
    pub fn names(&self) -> Vec<&str> {
        self.expressions.iter().map(|e| e.name.as_str()).collect()
    }

    /// Selects presets by a comma-separated list, or `all`.
    pub fn select(&self, list: &str) -> Result<Vec<&Expression>> {
        if list.trim() == "all" {
            return Ok(self.expressions.iter().collect());
        }
        list.split(',')
            .map(|name| self.lookup(name.trim(), "expression"))
            .collect()
    }

    /// The preset called `name`, or an error naming it as a `what` (expression, preset) and
    /// listing the known ones.
    pub fn lookup(&self, name: &str, what: &str) -> Result<&Expression> {
        self.get(name).ok_or_else(|| {
            FemError::Definition(format!(
                "unknown {what} `{name}` (known: {})",
                self.names().join(", ")
            ))
            .into()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::muscles::MuscleSet;

    #[test]
    fn builtin_presets_name_known_muscles() {
        let set = ExpressionSet::builtin();
        assert_eq!(set.expressions.len(), 18);
        let muscles = MuscleSet::builtin();
        // Waters' 9 pairs, then the 4 soft-tissue load pairs (see muscles.ron).
        assert_eq!(muscles.muscles.len(), 9);
        assert_eq!(muscles.bulges.len(), 4);
        assert_eq!(muscles.names().len(), 26);
        // The presets may also open the jaw (`jaw_open`, degrees).
        let names = muscles.actuator_names();
        assert_eq!(names.len(), 30);
        for e in &set.expressions {
            let a = e.activations_for(&names).unwrap();
            assert!(a.iter().any(|&x| x > 0.0), "{}", e.name);
        }
    }

    #[test]
    fn jaw_keys_never_pair_and_are_ignored_without_a_jaw() {
        let surprise = ExpressionSet::builtin().get("surprise").unwrap().clone();
        let with_jaw = MuscleSet::builtin().actuator_names();
        let a = surprise.activations_for(&with_jaw).unwrap();
        let open = with_jaw.iter().position(|n| n == "jaw_open").unwrap();
        assert!(a[open] > 0.0);
        // A muscle file written before the jaw gets the built-in one...
        let old = crate::fem::muscles::builtin_ron_before("jaw");
        let parsed = MuscleSet::parse(&old, Path::new("old.ron")).unwrap();
        assert_eq!(parsed.jaw, MuscleSet::builtin().jaw);
        // ...while `jaw: None` turns it off, and the presets' jaw keys are then ignored.
        let off = MuscleSet {
            jaw: None,
            ..MuscleSet::builtin()
        };
        let names = off.actuator_names();
        assert_eq!(names.len(), 26);
        let b = surprise.activations_for(&names).unwrap();
        assert_eq!(&b[..], &a[..26]);
        // "jaw" is not a left/right pair name: the two shifts would cancel.
        let pair = Expression {
            name: "t".into(),
            description: String::new(),
            action_units: vec![],
            activations: [("jaw".to_string(), 1.0)].into_iter().collect(),
        };
        assert!(pair.activations_for(&with_jaw).is_err());
    }

    #[test]
    fn one_sided_keys_override_pairs() {
        let names = vec!["zyg_left".to_string(), "zyg_right".to_string()];
        let e = Expression {
            name: "t".into(),
            description: String::new(),
            action_units: vec![],
            activations: [("zyg".to_string(), 1.0), ("zyg_right".to_string(), 0.25)]
                .into_iter()
                .collect(),
        };
        assert_eq!(e.activations_for(&names).unwrap(), vec![1.0, 0.25]);
        let bad = Expression {
            activations: [("nope".to_string(), 1.0)].into_iter().collect(),
            ..e
        };
        assert!(bad.activations_for(&names).is_err());
    }
}
