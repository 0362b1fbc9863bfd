//! Statistical comparison of the clustering runs (paper VI-C), as written to
//! `statistics.json` (SPEC-cli keys: `gcuk-euclidean-vs-brdf-it`, `friedman-<metric>`).

use crate::select::ClusteringSet;
use crate::stats::{friedman, mann_whitney_u, median, nemenyi, wilcoxon_signed_rank, PMethod};
use std::collections::BTreeMap;

/// Friedman test over the methods of one metric (blocks: run indices), with Nemenyi.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FriedmanSummary {
    /// Methods, in column order.
    pub methods: Vec<String>,
    /// Number of blocks (runs).
    pub blocks: usize,
    /// Tie-corrected chi-square statistic.
    pub statistic: f64,
    /// Its p-value.
    pub p_value: f64,
    /// Mean rank per method (1 = lowest DB).
    pub mean_ranks: Vec<f64>,
    /// Iman-Davenport F (`null` when the rankings agree perfectly: +inf).
    pub iman_davenport_f: Option<f64>,
    /// Iman-Davenport p-value.
    pub iman_davenport_p: f64,
    /// Nemenyi critical difference of mean ranks at alpha 0.05.
    pub nemenyi_cd: f64,
    /// Median DB per method.
    pub median_db: Vec<f64>,
}

/// Two-sample comparison of the DB indices of two sets of runs.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PairComparison {
    /// First sample (`metric/method`).
    pub a: String,
    /// Second sample.
    pub b: String,
    /// Number of paired runs.
    pub runs: usize,
    /// Wilcoxon signed-rank statistic `min(W+, W-)` of `a - b`, paired by run.
    pub wilcoxon_w: f64,
    /// Its two-sided p-value.
    pub wilcoxon_p: f64,
    /// How the Wilcoxon p-value was computed.
    pub wilcoxon_method: PMethod,
    /// Mann-Whitney U of `a` (independent samples).
    pub mann_whitney_u: f64,
    /// Its two-sided p-value (normal approximation).
    pub mann_whitney_p: f64,
    /// Median DB of `a`.
    pub median_a: f64,
    /// Median DB of `b`.
    pub median_b: f64,
}

/// The key of a metric's Friedman summary in `statistics.json`: written
/// `friedman-<metric>` (SPEC-cli), read back only with that prefix, held as the metric.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct FriedmanKey {
    metric: String,
}

impl FriedmanKey {
    /// The key's prefix in `statistics.json`.
    pub const PREFIX: &'static str = "friedman-";

    /// The key of `metric`'s summary.
    pub fn new(metric: impl Into<String>) -> Self {
        FriedmanKey {
            metric: metric.into(),
        }
    }

    /// The metric label (`euclidean`, `brdf-it`, ...).
    pub fn metric(&self) -> &str {
        &self.metric
    }
}

impl std::fmt::Display for FriedmanKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}{}", Self::PREFIX, self.metric)
    }
}

impl serde::Serialize for FriedmanKey {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> serde::Deserialize<'de> for FriedmanKey {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let key = String::deserialize(d)?;
        match key.strip_prefix(Self::PREFIX) {
            Some(m) if !m.is_empty() => Ok(FriedmanKey::new(m)),
            _ => Err(serde::de::Error::custom(format!(
                "unknown key `{key}` (expected `gcuk-euclidean-vs-brdf-it`, `not_computed` or `{}<metric>`)",
                Self::PREFIX
            ))),
        }
    }
}

/// `statistics.json`.
#[derive(Clone, Debug, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Statistics {
    /// GCUK with Euclidean against GCUK with BRDF_it.
    #[serde(
        rename = "gcuk-euclidean-vs-brdf-it",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub gcuk_euclidean_vs_brdf_it: Option<PairComparison>,
    /// Tests that could not be computed, with the reason.
    #[serde(default)]
    pub not_computed: Vec<String>,
    /// `friedman-<metric>` entries.
    #[serde(flatten)]
    pub friedman: BTreeMap<FriedmanKey, FriedmanSummary>,
}

impl Statistics {
    /// The Friedman summary of `metric`, if computed.
    pub fn friedman_of(&self, metric: &str) -> Option<&FriedmanSummary> {
        self.friedman.get(&FriedmanKey::new(metric))
    }
}

/// Friedman + Nemenyi per metric over its methods, and the GCUK Euclidean vs BRDF_it
/// comparison.
pub fn compare(metrics: &[String], sets: &[ClusteringSet], runs: usize) -> Statistics {
    let mut out = Statistics::default();
    for m in metrics {
        let cols: Vec<&ClusteringSet> = sets.iter().filter(|s| &s.metric == m).collect();
        let blocks: Vec<Vec<f64>> = (0..runs)
            .map(|r| cols.iter().map(|c| c.runs[r].db_index).collect())
            .collect();
        let f = friedman(&blocks)
            .map_err(|e| e.to_string())
            .and_then(|f| nemenyi(&f, 0.05).map(|n| (f, n)).map_err(|e| e.to_string()));
        match f {
            Ok((f, n)) => {
                out.friedman.insert(
                    FriedmanKey::new(m.as_str()),
                    FriedmanSummary {
                        methods: cols.iter().map(|c| c.method.clone()).collect(),
                        blocks: f.blocks,
                        statistic: f.statistic,
                        p_value: f.p_value,
                        mean_ranks: f.mean_ranks,
                        iman_davenport_f: Some(f.iman_davenport.statistic)
                            .filter(|v| v.is_finite()),
                        iman_davenport_p: f.iman_davenport.p_value,
                        nemenyi_cd: n.critical_difference,
                        median_db: cols.iter().map(|c| median(&c.db_values())).collect(),
                    },
                );
            }
            Err(e) => out
                .not_computed
                .push(format!("Friedman ({m}, {runs} runs): {e}")),
        }
    }
    let find = |m: &str| sets.iter().find(|s| s.metric == m && s.method == "gcuk");
    if let (Some(a), Some(b)) = (find("euclidean"), find("brdf-it")) {
        let (x, y) = (a.db_values(), b.db_values());
        match (wilcoxon_signed_rank(&x, &y), mann_whitney_u(&x, &y)) {
            (Ok(w), Ok(u)) => {
                out.gcuk_euclidean_vs_brdf_it = Some(PairComparison {
                    a: "euclidean/gcuk".into(),
                    b: "brdf-it/gcuk".into(),
                    runs: x.len(),
                    wilcoxon_w: w.statistic,
                    wilcoxon_p: w.p_value,
                    wilcoxon_method: w.method,
                    mann_whitney_u: u.u,
                    mann_whitney_p: u.p_value,
                    median_a: median(&x),
                    median_b: median(&y),
                })
            }
            (w, u) => out.not_computed.push(format!(
                "GCUK Euclidean vs BRDF_it: {}",
                [w.err(), u.err()]
                    .into_iter()
                    .flatten()
                    .map(|e| e.to_string())
                    .collect::<Vec<_>>()
                    .join("; ")
            )),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn summary() -> FriedmanSummary {
        FriedmanSummary {
            methods: vec!["a".into(), "b".into()],
            blocks: 3,
            statistic: 3.0,
            p_value: 0.08,
            mean_ranks: vec![1.0, 2.0],
            iman_davenport_f: None,
            iman_davenport_p: 0.0,
            nemenyi_cd: 1.13,
            median_db: vec![0.1, 0.2],
        }
    }

    /// Keys are written `friedman-<metric>` as before, read back typed, and a key without
    /// the prefix is refused instead of being taken for a metric.
    #[test]
    fn friedman_keys_round_trip_and_are_checked() {
        let mut st = Statistics::default();
        st.friedman.insert(FriedmanKey::new("brdf-it"), summary());
        let text = serde_json::to_string(&st).unwrap();
        assert!(text.contains("\"friedman-brdf-it\":{"), "{text}");
        let back: Statistics = serde_json::from_str(&text).unwrap();
        assert_eq!(back, st);
        assert_eq!(back.friedman_of("brdf-it"), Some(&summary()));
        assert_eq!(back.friedman.keys().next().unwrap().metric(), "brdf-it");
        let bad = text.replace("friedman-brdf-it", "brdf-it");
        let err = serde_json::from_str::<Statistics>(&bad).unwrap_err();
        assert!(err.to_string().contains("brdf-it"), "{err}");
    }
}
