//! Figures of measurement sets: an FRF set as one curve per FRF, named by its nodes, and the
//! stabilisation diagram of a set's modal fit (`modal.fit_set`) over the summed `|H|`.

use super::PlotError;
use super::figure::{Axis, Panel, Series, Style};
use crate::value::{Table, Value};

/// The FRFs of a set as separate values with their legend names (`response 1 x / reference 3
/// x`), each name prefixed by `prefix` when it is not empty (a sweep point of the set's step).
pub fn members(v: &Value, prefix: &str) -> Vec<(String, Value)> {
    match v {
        Value::FrfSet(s) => s
            .frfs
            .iter()
            .enumerate()
            .map(|(i, f)| {
                let name = s.name(i);
                let name = if prefix.is_empty() { name } else { format!("{prefix}: {name}") };
                (name, Value::Frf(f.clone()))
            })
            .collect(),
        other => vec![(prefix.to_string(), other.clone())],
    }
}

/// The columns that make a table a stabilisation diagram (as `modal.fit_set` writes it).
const COLUMNS: [&str; 5] = ["order", "frequency", "stable_frequency", "stable_damping", "selected"];

fn col<'a>(t: &'a Table, name: &str) -> Option<&'a [f64]> {
    t.columns.iter().find(|c| c.name == name).map(|c| c.values.as_slice())
}

/// Whether `t` is a stabilisation diagram.
pub fn is_stabilisation(t: &Table) -> bool {
    COLUMNS.iter().all(|c| col(t, c).is_some())
}

/// The stabilisation diagram: every pole at its frequency (x) and model order (y), a dot when
/// it is new at its order, a circle when stable in frequency (`f`), a cross when stable in
/// frequency and damping (`f and ζ`), the selected poles as vertical lines; behind them the summed `|H|` of the
/// `behind` FRFs and sets (log scale, stretched over the order axis).
pub fn stabilisation(t: &Table, behind: &[&Value]) -> Result<Vec<Panel>, PlotError> {
    let get = |name: &str| col(t, name).ok_or(PlotError::Empty);
    let (order, freq) = (get("order")?, get("frequency")?);
    let (sf, sd, sel) = (get("stable_frequency")?, get("stable_damping")?, get("selected")?);
    let top = order.iter().copied().fold(0.0, f64::max);
    let mut p = Panel::new(Axis::linear("frequency [Hz]"), Axis::linear("model order").fixed(0.0, top.max(2.0) + 2.0));
    p.weight = 3;
    // The summed |H| of what is drawn behind, as log10 mapped onto [0, top].
    let mut sum: Vec<(f64, f64)> = Vec::new();
    for v in behind {
        let frfs: Vec<&crate::value::Frf> = match v {
            Value::Frf(f) => vec![f],
            Value::FrfSet(s) => s.frfs.iter().collect(),
            other => {
                return Err(PlotError::Mixed(format!(
                    "a stabilisation diagram takes FRFs or FRF sets behind it, not a {}",
                    other.port_type()
                )));
            }
        };
        for f in frfs {
            if sum.is_empty() {
                sum = f.freq_hz.iter().map(|&x| (x, 0.0)).collect();
            }
            if f.freq_hz.len() != sum.len() {
                return Err(PlotError::Mixed("the FRFs behind a stabilisation diagram differ in their lines".into()));
            }
            for (s, v) in sum.iter_mut().zip(&f.values) {
                s.1 += v.norm();
            }
        }
    }
    let (lo, hi) = freq.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &f| (a.min(f), b.max(f)));
    let shown: Vec<(f64, f64)> =
        sum.into_iter().filter(|(x, y)| *y > 0.0 && y.is_finite() && (lo..=hi).contains(x)).collect();
    if !shown.is_empty() && top > 0.0 {
        let (a, b) = shown.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (_, y)| {
            let l = y.log10();
            (a.min(l), b.max(l))
        });
        let span = (b - a).max(1e-12);
        let line = shown.iter().map(|(x, y)| (*x, (y.log10() - a) / span * top)).collect();
        p.series.push(Series::new("Σ|H| (log scale)", line, Style::Line, 7));
    }
    // Columns of one table have one length; a shorter one (a table made elsewhere) bounds the rows.
    let rows = [order.len(), freq.len(), sf.len(), sd.len(), sel.len()].into_iter().min().unwrap_or(0);
    let pick = |keep: &dyn Fn(usize) -> bool| -> Vec<(f64, f64)> {
        (0..rows).filter(|&i| keep(i)).map(|i| (freq[i], order[i])).collect()
    };
    let new = pick(&|i| sf[i] == 0.0);
    let frequency = pick(&|i| sf[i] == 1.0 && sd[i] == 0.0);
    let damping = pick(&|i| sd[i] == 1.0);
    let selected = pick(&|i| sel[i] == 1.0);
    p.series.push(Series::new("new", new, Style::Dots, 8));
    p.series.push(Series::new("stable in f", frequency, Style::Circles, 1));
    p.series.push(Series::new("stable in f and ζ", damping, Style::Crosses, 2));
    if !selected.is_empty() {
        p.series.push(Series::new("selected", selected.clone(), Style::VLines, 3));
        p.series.push(Series::new("", selected, Style::Circles, 3));
    }
    Ok(vec![p])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::value::{Column, Frf, FrfDofs, FrfSet, UnitLabel};
    use num_complex::Complex64;

    #[test]
    fn a_stabilisation_table_draws_its_classes_over_the_summed_frf() {
        let t = Table {
            columns: vec![
                Column::new("order", "", vec![2.0, 4.0, 4.0, 6.0]),
                Column::new("frequency", "Hz", vec![100.0, 101.0, 300.0, 100.5]),
                Column::new("damping_ratio", "", vec![0.01; 4]),
                Column::new("stable_frequency", "", vec![0.0, 1.0, 0.0, 1.0]),
                Column::new("stable_damping", "", vec![0.0, 0.0, 0.0, 1.0]),
                Column::new("selected", "", vec![0.0, 0.0, 0.0, 1.0]),
            ],
        };
        assert!(is_stabilisation(&t));
        let frf = |k: f64, node: i64| Frf {
            freq_hz: vec![50.0, 100.0, 150.0, 300.0],
            values: vec![
                Complex64::new(k, 0.0),
                Complex64::new(10.0 * k, 0.0),
                Complex64::new(k, 1.0),
                Complex64::new(2.0, 0.0),
            ],
            coherence: None,
            unit: UnitLabel::new("m/N"),
            direction: None,
            speed: None,
            sensor: None,
            dofs: Some(FrfDofs {
                response_node: 1,
                response_direction: 1,
                reference_node: node,
                reference_direction: 1,
            }),
        };
        let set = Value::FrfSet(FrfSet::new(vec![frf(1.0, 1), frf(2.0, 2)]).unwrap());
        let panels = stabilisation(&t, &[&set]).unwrap();
        let s = &panels[0].series;
        let names: Vec<&str> = s.iter().map(|x| x.name.as_str()).collect();
        assert_eq!(names, ["Σ|H| (log scale)", "new", "stable in f", "stable in f and ζ", "selected", ""]);
        // The summed |H| peaks at 100 Hz, drawn at the top order; its lowest line at order 0.
        let sum = &s[0].points;
        assert_eq!(sum.iter().map(|p| p.0).collect::<Vec<_>>(), [100.0, 150.0, 300.0]);
        assert!((sum[0].1 - 6.0).abs() < 1e-12 && sum.iter().any(|p| p.1 == 0.0));
        assert_eq!(s[3].points, [(100.5, 6.0)]);
        let named = members(&set, "");
        assert_eq!(named[1].0, "response 1 x / reference 2 x");
    }
}
