//! Output writers: CSV, JSON and UFF dataset 58, written to a staging directory and moved
//! into place only when every output of the run is ready. Time series and FRFs are written by
//! the same functions as [`crate::formats`] uses, so the readers read back what is written here.

use super::manifest::MissingPoint;
use crate::formats::{csv, frf_set, uff};
use crate::model::OutputFormat;
use crate::value::{Table, Value};
use spindlelab_domain::Speed;
use std::fmt::Write as _;

/// One value to write, with the sweep label of the instance that made it (`speed=1500 rpm,
/// direction=x`: the sweep coordinates as the recipe wrote them).
pub struct Row<'a> {
    pub label: &'a str,
    pub value: &'a Value,
}

/// Renders the values of one output (several when its step is swept) in the given format.
pub fn render(format: OutputFormat, rows: &[Row]) -> String {
    render_partial(format, rows, &[])
}

/// Renders a swept output some of whose sweep points are `missing` (written with
/// `--keep-going`): CSV lists them in `# missing:` lines before the header, JSON as items with
/// a `missing` reason in place of a `value`. UFF has no place for them; the manifest lists
/// them for every format.
pub fn render_partial(format: OutputFormat, rows: &[Row], missing: &[MissingPoint]) -> String {
    match format {
        OutputFormat::Json => render_json(rows, missing),
        OutputFormat::Csv => {
            let mut out = String::new();
            for m in missing {
                let reason = m.reason.split_whitespace().collect::<Vec<_>>().join(" ");
                let _ = writeln!(out, "# missing: {} ({reason})", m.label);
            }
            out.push_str(&render_csv(rows));
            out
        }
        OutputFormat::Uff => render_uff(rows),
        // Drawn by `crate::plot` from the values, not rendered as text.
        OutputFormat::Plot(_) => String::new(),
    }
}

/// One dataset 58 per FRF, one per channel of a time series, four (H, L, N, P) per receptance
/// set, each with its sweep label in ID line 2. The resolver admits only these to a `.uff` file.
fn render_uff(rows: &[Row]) -> String {
    let mut out = String::new();
    for r in rows {
        match r.value {
            Value::Frf(f) if f.direction.is_none() || f.speed.is_none() => {
                // The sweep says what the value does not: an FRF estimated from a record made
                // at `direction=x` is in x, so its dataset reads back with `direction: x`.
                let cols = label_columns(r.label);
                let of = |k: &str| cols.iter().find(|(n, _)| n == k).map(|(_, v)| v.clone());
                let mut f = f.clone();
                f.direction = f.direction.or_else(|| of("direction").filter(|d| ["x", "y", "z"].contains(&d.as_str())));
                f.speed = f.speed.or_else(|| of("speed_rpm").and_then(|v| v.parse().ok()).map(Speed::from_rpm));
                uff::write_frf(&mut out, &f, r.label)
            }
            Value::Frf(f) => uff::write_frf(&mut out, f, r.label),
            Value::TimeSeries(ts) => uff::write_time_series(&mut out, ts, r.label),
            Value::ReceptanceSet(rs) => uff::write_receptance(&mut out, rs, r.label),
            Value::FrfSet(set) => frf_set::write_uff(&mut out, set, r.label),
            other => debug_assert!(false, "no UFF form for a {}", other.port_type()),
        }
    }
    out
}

fn render_json(rows: &[Row], missing: &[MissingPoint]) -> String {
    if rows.len() == 1 && rows[0].label.is_empty() && missing.is_empty() {
        return serde_json::to_string_pretty(&plain(rows[0].value)).unwrap_or_default() + "\n";
    }
    let item = |label: &str, key: &str, v: serde_json::Value| {
        let mut m = serde_json::Map::new();
        m.insert("label".into(), label.into());
        for (name, cell) in label_columns(label) {
            let v = cell.parse::<f64>().map_or_else(|_| serde_json::Value::from(cell.clone()), serde_json::Value::from);
            m.insert(name, v);
        }
        m.insert(key.into(), v);
        serde_json::Value::Object(m)
    };
    let items: Vec<serde_json::Value> = rows
        .iter()
        .map(|r| item(r.label, "value", plain(r.value)))
        .chain(missing.iter().map(|m| item(&m.label, "missing", m.reason.clone().into())))
        .collect();
    serde_json::to_string_pretty(&items).unwrap_or_default() + "\n"
}

/// A value as a plain JSON object (`{"speed_rpm": […], …}`), without the name of its type
/// around it.
fn plain(v: &Value) -> serde_json::Value {
    let mut j = match serde_json::to_value(v).unwrap_or_default() {
        serde_json::Value::Object(mut m) if m.len() == 1 => {
            m.values_mut().next().map(std::mem::take).unwrap_or_default()
        }
        other => other,
    };
    // A numeric column's empty `levels` says nothing; the reader defaults it.
    if let (Value::Table(_), Some(columns)) = (v, j.get_mut("columns").and_then(|c| c.as_array_mut())) {
        for c in columns.iter_mut().filter_map(|c| c.as_object_mut()) {
            if c.get("levels").and_then(|l| l.as_array()).is_some_and(|l| l.is_empty()) {
                c.remove("levels");
            }
        }
    }
    j
}

/// A text cell: a comma would split it and a quote or line break end it, so those become
/// `;` and a space.
fn word(w: &str) -> String {
    w.replace(',', ";").replace(['"', '\n', '\r'], " ")
}

fn num(v: f64) -> String {
    // Round-trip precision; CSV readers get the exact double.
    zmij::Buffer::new().format(v).to_string()
}

/// The sweep coordinates of a label as file columns, numbers in the unit the recipe wrote:
/// `speed=1500 rpm, direction=x` → `[("speed_rpm", "1500"), ("direction", "x")]`.
pub fn label_columns(label: &str) -> Vec<(String, String)> {
    label
        .split(", ")
        .filter_map(|part| part.split_once('='))
        .map(|(name, value)| {
            let mut words = value.split_whitespace();
            let first = words.next().unwrap_or("");
            let unit: Vec<&str> = words.collect();
            match first.parse::<f64>() {
                Ok(_) if unit.is_empty() => (name.to_string(), first.to_string()),
                Ok(_) => (format!("{name}_{}", unit_tag(&unit.join(""))), first.to_string()),
                // Text as one cell: no separators or quotes inside it.
                Err(_) => (name.to_string(), value.replace([',', '"'], ";")),
            }
        })
        .collect()
}

fn render_csv(rows: &[Row]) -> String {
    let mut out = String::new();
    let swept = rows.len() > 1 || rows.first().is_some_and(|r| !r.label.is_empty());
    // A sweep coordinate a table holds as a column of its own (a simulated cut's speed and
    // depth) is written once, in the table.
    let own: Vec<&str> = match rows.first().map(|r| r.value) {
        Some(Value::Table(t)) => t.columns.iter().map(|c| c.name.as_str()).collect(),
        _ => Vec::new(),
    };
    let label_columns = |label: &str| -> Vec<(String, String)> {
        let coords = label.split(", ").filter_map(|p| p.split_once('=')).map(|(n, _)| n);
        label_columns(label).into_iter().zip(coords).filter(|(_, n)| !own.contains(n)).map(|(c, _)| c).collect()
    };
    let named = rows.first().map(|r| label_columns(r.label)).unwrap_or_default();
    // A label without `name=value` coordinates goes out whole, as one text column.
    let bare = swept && rows.first().is_some_and(|r| !r.label.contains('='));
    let prefix_header: String =
        if bare { "label,".to_string() } else { named.iter().map(|(n, _)| format!("{n},")).collect() };
    let prefix = |r: &Row| -> String {
        if bare {
            format!("\"{}\",", r.label.replace('"', "'"))
        } else {
            label_columns(r.label).into_iter().map(|(_, v)| format!("{v},")).collect()
        }
    };
    let mut header_done = false;
    for r in rows {
        match r.value {
            Value::Scalar(s) => {
                if !header_done {
                    // `value_m`, or `value` for a plain number.
                    let name = match unit_tag(&s.unit.symbol) {
                        tag if tag.is_empty() => "value".to_string(),
                        tag => format!("value_{tag}"),
                    };
                    let _ = writeln!(out, "# units: {name}={}", s.unit.symbol);
                    let _ = writeln!(out, "{prefix_header}{name}");
                    header_done = true;
                }
                let _ = writeln!(out, "{}{}", prefix(r), num(s.value));
            }
            Value::Table(t) => table_rows(&mut out, t, &prefix_header, &prefix(r), &mut header_done),
            Value::TimeSeries(ts) => csv::time_series_rows(&mut out, ts, &prefix_header, &prefix(r), &mut header_done),
            Value::Frf(f) => csv::frf_rows(&mut out, f, &prefix_header, &prefix(r), &mut header_done),
            Value::ReceptanceSet(rs) => {
                csv::receptance_rows(&mut out, rs, &prefix_header, &prefix(r), &mut header_done)
            }
            Value::Lobes(l) => csv::lobes_rows(&mut out, l, &prefix_header, &prefix(r), &mut header_done),
            Value::FrfSet(set) => frf_set::csv_rows(&mut out, set, &prefix_header, &prefix(r), &mut header_done),
            other => {
                // Structured values without a tabular form go out as one JSON cell per row.
                if !header_done {
                    let _ = writeln!(out, "{prefix_header}json");
                    header_done = true;
                }
                let json = serde_json::to_string(other).unwrap_or_default().replace('"', "\"\"");
                let _ = writeln!(out, "{}\"{json}\"", prefix(r));
            }
        }
    }
    out
}

/// A unit as a column-name suffix: `m/N` → `m_per_N`, `rad*s` → `rad_s`, `m/s^2` → `m_per_s2`.
fn unit_tag(symbol: &str) -> String {
    symbol.replace('/', "_per_").replace(['*', '·', ' '], "_").replace('^', "")
}

fn table_rows(out: &mut String, t: &Table, ph: &str, p: &str, header_done: &mut bool) {
    if !*header_done {
        // The units exactly as the values hold them, for the reader (a header tag is lossy).
        let units: Vec<String> = t.columns.iter().map(|c| format!("{}={}", c.name, c.unit.symbol)).collect();
        let _ = writeln!(out, "# units: {}", units.join(", "));
        let text: Vec<&str> = t.columns.iter().filter(|c| c.is_text()).map(|c| c.name.as_str()).collect();
        if !text.is_empty() {
            let _ = writeln!(out, "# text: {}", text.join(", "));
        }
        let cols: Vec<String> = t
            .columns
            .iter()
            .map(|c| {
                if c.unit.symbol.is_empty() {
                    c.name.clone()
                } else {
                    format!("{}_{}", c.name, unit_tag(&c.unit.symbol))
                }
            })
            .collect();
        let _ = writeln!(out, "{ph}{}", cols.join(","));
        *header_done = true;
    }
    for i in 0..t.rows() {
        let cells: Vec<String> = t
            .columns
            .iter()
            .map(|c| if c.is_text() { word(c.word(i).unwrap_or("")) } else { num(c.values[i]) })
            .collect();
        let _ = writeln!(out, "{p}{}", cells.join(","));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::{self, uff::Dataset58};
    use crate::value::{Channel, Frf, TimeSeries, UnitLabel};
    use num_complex::Complex64;

    fn series(scale: f64) -> Value {
        Value::TimeSeries(TimeSeries {
            sample_rate: 100_000.0,
            t0: -0.001,
            channels: vec![
                Channel {
                    name: "force".into(),
                    unit: UnitLabel::new("N"),
                    samples: (0..20).map(|i| scale * (i as f64 / 3.0).sin()).collect(),
                },
                Channel {
                    name: "response".into(),
                    unit: UnitLabel::new("m"),
                    samples: (0..20).map(|i| scale * 1e-6 / (i as f64 + 7.0)).collect(),
                },
            ],
        })
    }

    fn frf(k: f64) -> Value {
        Value::Frf(Frf {
            freq_hz: (0..64).map(|i| i as f64 * 12.5).collect(),
            values: (0..64).map(|i| Complex64::new(1.0, -(i as f64) / k) / (1e7 * k)).collect(),
            coherence: None,
            unit: UnitLabel::new("m/N"),
            direction: Some("x".into()),
            speed: None,
            sensor: None,
            dofs: None,
        })
    }

    #[test]
    fn an_unswept_csv_output_reads_back_exactly() {
        let v = series(1.0 / 3.0);
        let text = render(OutputFormat::Csv, &[Row { label: "", value: &v }]);
        let Value::TimeSeries(ts) = &v else { unreachable!() };
        assert_eq!(text, formats::csv::write_time_series(ts));
        assert_eq!(&formats::csv::read_time_series(text.as_bytes(), "o.csv").unwrap(), ts);
        let f = frf(3.0);
        let text = render(OutputFormat::Csv, &[Row { label: "", value: &f }]);
        assert_eq!(Value::Frf(formats::csv::read_frf(text.as_bytes(), "o.csv").unwrap()), f);
    }

    #[test]
    fn a_receptance_set_output_reads_back_from_csv_exactly_and_from_uff() {
        let rs = crate::formats::csv::tests::receptance_set();
        let v = Value::ReceptanceSet(rs.clone());
        let rows = [Row { label: "", value: &v }];
        let text = render(OutputFormat::Csv, &rows);
        assert_eq!(formats::csv::read_receptance(text.as_bytes(), "r.csv").unwrap(), rs);
        let text = render(OutputFormat::Uff, &rows);
        let file = formats::uff::parse(text.as_bytes(), "r.uff").unwrap();
        let (back, _) = formats::uff::to_receptance(&file, "r.uff", None).unwrap();
        for (a, b) in back.p.iter().zip(&rs.p) {
            assert!((a - b).norm() <= 1e-12 * b.norm(), "{a} vs {b}");
        }
        let json = render(OutputFormat::Json, &rows);
        assert_eq!(formats::read_json_value(&json, v.port_type()).unwrap(), v);
    }

    #[test]
    fn a_swept_uff_output_has_one_dataset_per_point_and_channel_with_its_label() {
        let ks = [1.0, 2.0, 3.0];
        let values: Vec<Value> = ks.iter().map(|k| frf(*k)).collect();
        let labels: Vec<String> = ks.iter().map(|k| format!("k={k}")).collect();
        let rows: Vec<Row> = values.iter().zip(&labels).map(|(value, label)| Row { label, value }).collect();
        let text = render(OutputFormat::Uff, &rows);
        let file = formats::uff::parse(text.as_bytes(), "s.uff").unwrap();
        assert_eq!(file.datasets.len(), 3);
        for ((d, label), v) in file.datasets.iter().zip(&labels).zip(&values) {
            assert_eq!(&d.id[1], label);
            let (Value::Frf(want), got) = (v, d.to_frf("s.uff").unwrap()) else { unreachable!() };
            for (a, b) in got.values.iter().zip(&want.values) {
                assert!((a - b).norm() <= 1e-12 * b.norm(), "{a} vs {b}");
            }
            assert_eq!(got.freq_hz, want.freq_hz);
        }

        let ts = [series(1.0), series(2.0)];
        let rows: Vec<Row> = ts.iter().zip(["a=1", "a=2"]).map(|(value, label)| Row { label, value }).collect();
        let text = render(OutputFormat::Uff, &rows);
        let file = formats::uff::parse(text.as_bytes(), "t.uff").unwrap();
        let ids: Vec<(&str, &str)> = file.datasets.iter().map(|d| (d.id[0].as_str(), d.id[1].as_str())).collect();
        assert_eq!(ids, [("force", "a=1"), ("response", "a=1"), ("force", "a=2"), ("response", "a=2")]);
        let Value::TimeSeries(second) = &ts[1] else { unreachable!() };
        let mut expect = String::new();
        formats::uff::write_dataset(&mut expect, &Dataset58::from_channel(second, &second.channels[1], "a=2"));
        assert!(text.ends_with(&expect));
    }

    #[test]
    fn a_swept_frf_csv_reads_back_per_sweep_point_with_its_coordinates_as_written() {
        let values: Vec<Value> = [1.0, 2.0, 3.0, 4.0].iter().map(|k| frf(*k)).collect();
        let labels = [
            "speed=0 rpm, direction=x",
            "speed=0 rpm, direction=y",
            "speed=1500 rpm, direction=x",
            "speed=1500 rpm, direction=y",
        ];
        let rows: Vec<Row> = values.iter().zip(labels).map(|(value, label)| Row { label, value }).collect();
        let text = render(OutputFormat::Csv, &rows);
        assert!(text.contains("\nspeed_rpm,direction,freq_hz,real,imag\n"), "{}", &text[..200]);
        let blocks = formats::csv::read_frf_blocks(text.as_bytes(), "s.csv").unwrap();
        assert_eq!(blocks.len(), 4);
        for ((b, v), label) in blocks.iter().zip(&values).zip(labels) {
            let Value::Frf(want) = v else { unreachable!() };
            assert_eq!(b.frf.values, want.values, "{label}");
            assert_eq!(b.frf.freq_hz, want.freq_hz);
            assert_eq!(
                formats::csv::block_names(std::slice::from_ref(b))[0],
                label.replace("speed=", "speed_rpm=").replace(" rpm", "")
            );
        }
        assert_eq!(
            (blocks[3].frf.direction.as_deref(), blocks[3].frf.speed.map(Speed::rpm_as_written)),
            (Some("y"), Some(1500.0))
        );
        // One FRF of several is not read as if it were the only one.
        let e = formats::csv::read_frf(text.as_bytes(), "s.csv").unwrap_err().to_string();
        assert!(e.contains("holds 4 sweep points") && e.contains("`dataset: K`"), "{e}");
    }

    #[test]
    fn a_swept_frf_uff_carries_the_sweep_direction_and_speed_when_the_frf_does_not() {
        let mut f = frf(2.0);
        if let Value::Frf(x) = &mut f {
            x.direction = None;
        }
        let rows = [Row { label: "speed=1500 rpm, direction=y", value: &f }];
        let text = render(OutputFormat::Uff, &rows);
        let file = formats::uff::parse(text.as_bytes(), "d.uff").unwrap();
        let back = file.datasets[0].to_frf("d.uff").unwrap();
        assert_eq!((back.direction.as_deref(), back.speed.map(Speed::rpm_as_written)), (Some("y"), Some(1500.0)));
    }

    #[test]
    fn infinite_and_missing_numbers_read_back_from_json_and_say_what_they_are() {
        let lobes = Value::Lobes(crate::value::Lobes {
            speed: vec![1000.0, 2000.0].into_iter().map(Speed::from_rpm).collect(),
            depth_limit: vec![f64::INFINITY, 1e-3],
            chatter_hz: vec![f64::NAN, 900.0],
        });
        let json = render(OutputFormat::Json, &[Row { label: "", value: &lobes }]);
        assert!(json.contains("\"inf\"") && json.contains("\"NaN\"") && !json.contains("null"), "{json}");
        let Value::Lobes(back) = formats::read_json_value(&json, lobes.port_type()).unwrap() else {
            panic!("not lobes")
        };
        assert!(!json.contains("\"Lobes\""), "a plain object: {json}");
        assert_eq!(back.depth_limit, [f64::INFINITY, 1e-3]);
        assert!(back.chatter_hz[0].is_nan() && back.chatter_hz[1] == 900.0);
        // The cache's binary form keeps the numbers themselves.
        let bytes = postcard::to_stdvec(&lobes).unwrap();
        let Value::Lobes(b) = postcard::from_bytes::<Value>(&bytes).unwrap() else { panic!() };
        assert_eq!(b.depth_limit[0], f64::INFINITY);
    }

    #[test]
    fn tables_lobes_and_scalars_read_back_swept_with_their_units_and_non_finite_values() {
        use crate::value::{Column, Lobes, Scalar, Table};
        let t = |k: f64| {
            Value::Table(Table {
                columns: vec![
                    Column::new("speed", "rpm", vec![1000.0 * k, 2000.0]),
                    Column::new("depth", "m", vec![1e-3, f64::NAN]),
                    Column::new("stiffness", "N/m", vec![f64::INFINITY, 2e7 * k]),
                ],
            })
        };
        let (a, b) = (t(1.0), t(2.0));
        let rows = [Row { label: "direction=x", value: &a }, Row { label: "direction=y", value: &b }];
        let text = render(OutputFormat::Csv, &rows);
        let back = formats::csv::read_tables(text.as_bytes(), "t.csv").unwrap();
        assert_eq!(back.len(), 2);
        for (blk, want) in back.iter().zip([&a, &b]) {
            let Value::Table(want) = want else { unreachable!() };
            for (c, w) in blk.table.columns.iter().zip(&want.columns) {
                assert_eq!((&c.name, &c.unit), (&w.name, &w.unit));
                let same = c.values.iter().zip(&w.values).all(|(x, y)| x == y || (x.is_nan() && y.is_nan()));
                assert!(same, "{}: {:?} vs {:?}", c.name, c.values, w.values);
            }
        }
        assert_eq!(back[1].coords, [("direction".to_string(), "y".to_string())]);

        let l = Value::Lobes(Lobes {
            speed: vec![1000.0, 2000.0].into_iter().map(Speed::from_rpm).collect(),
            depth_limit: vec![f64::INFINITY, 2e-3],
            chatter_hz: vec![f64::NAN, 950.0],
        });
        let text = render(OutputFormat::Csv, &[Row { label: "immersion=25 %", value: &l }]);
        let back = formats::csv::read_lobes(text.as_bytes(), "l.csv").unwrap();
        assert_eq!(back[0].0, [("immersion_%".to_string(), "25".to_string())]);
        assert_eq!(back[0].1.depth_limit, [f64::INFINITY, 2e-3]);
        assert!(back[0].1.chatter_hz[0].is_nan() && back[0].1.speeds_rpm() == [1000.0, 2000.0]);

        let (s1, s2) = (Value::Scalar(Scalar::new(0.25e-3, "s")), Value::Scalar(Scalar::new(f64::INFINITY, "s")));
        let rows = [Row { label: "hammer_mass=0.03 kg", value: &s1 }, Row { label: "hammer_mass=0.04 kg", value: &s2 }];
        let text = render(OutputFormat::Csv, &rows);
        let back = formats::csv::read_scalars(text.as_bytes(), "s.csv").unwrap();
        assert_eq!(back.len(), 2);
        assert_eq!((back[0].1, back[0].2.as_str()), (0.25e-3, "s"));
        assert_eq!(back[1].1, f64::INFINITY);
        assert_eq!(back[1].0, [("hammer_mass_kg".to_string(), "0.04".to_string())]);
    }

    /// Text columns are written as their words and read back as the same words, in CSV (named
    /// by `# text:`) and in JSON; a word with a comma comes back with `;`.
    #[test]
    fn text_columns_read_back_as_words() {
        use crate::value::{Column, PortType, Table};
        let t = Value::Table(Table {
            columns: vec![
                Column::new("ratio", "", vec![1.5, 0.9, 1.0]),
                Column::text("direction", &["x", "y", "x"]),
                Column::text("node", &["3", "tip, left", ""]),
            ],
        });
        let text = render(OutputFormat::Csv, &[Row { label: "speed=3000 rpm", value: &t }]);
        assert!(text.contains("# text: direction, node\n") && text.contains(",1.5,x,3\n"), "{text}");
        let back = formats::csv::read_tables(text.as_bytes(), "t.csv").unwrap();
        let words = |c: &Column| (0..c.values.len()).map(|i| c.word(i).unwrap().to_string()).collect::<Vec<_>>();
        let cols = &back[0].table.columns;
        assert_eq!(cols[0].values, [1.5, 0.9, 1.0]);
        assert!(!cols[0].is_text());
        assert_eq!(words(&cols[1]), ["x", "y", "x"]);
        assert_eq!(words(&cols[2]), ["3", "tip; left", ""]);
        let json = render(OutputFormat::Json, &[Row { label: "", value: &t }]);
        let Value::Table(j) = formats::read_json_value(&json, PortType::Table).unwrap() else { panic!() };
        assert_eq!(Value::Table(j), t);
        assert!(!json.contains("\"levels\": []"), "{json}");
        // The cache's binary form keeps them too.
        let bytes = postcard::to_stdvec(&t).unwrap();
        assert_eq!(postcard::from_bytes::<Value>(&bytes).unwrap(), t);
        // A `# text:` naming no column of the table is refused at its line.
        let bad = "# units: a=\n# text: b\na\n1\n";
        let e = formats::csv::read_tables(bad.as_bytes(), "bad.csv").unwrap_err().to_string();
        assert!(e.starts_with("bad.csv:2") && e.contains("`b`"), "{e}");
    }

    /// A swept table that holds its sweep coordinates as columns (a simulated cut's speed and
    /// depth) writes each once, and reads back with them.
    #[test]
    fn a_sweep_coordinate_the_table_holds_is_written_once() {
        let cut = |speed: f64, depth: f64| {
            Value::Table(Table {
                columns: vec![
                    crate::value::Column::new("speed", "rpm", vec![speed]),
                    crate::value::Column::new("depth", "m", vec![depth]),
                    crate::value::Column::new("stable", "", vec![1.0]),
                ],
            })
        };
        let (a, b) = (cut(6000.0, 1e-3), cut(9000.0, 4e-3));
        let rows = [
            Row { label: "speed=6000 rpm, depth=1 mm, tool=a", value: &a },
            Row { label: "speed=9000 rpm, depth=4 mm, tool=a", value: &b },
        ];
        let text = render(OutputFormat::Csv, &rows);
        assert!(text.contains("\ntool,speed_rpm,depth_m,stable\n"), "{text}");
        let blocks = formats::csv::read_tables(text.as_bytes(), "cuts.csv").unwrap();
        let speeds: Vec<f64> = blocks.iter().flat_map(|b| b.table.columns[0].values.clone()).collect();
        assert_eq!(speeds, [6000.0, 9000.0]);
    }
}
