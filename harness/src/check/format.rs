//! JSON for files people review in diffs: one object key per line, arrays of numbers and
//! strings on one line (a baseline's figures per frame), two-space indentation, whole
//! numbers without a decimal point (`1000`, not `1000.0`; they read back as the same `f64`).

use serde_json::Value;

/// `v` as text, ending with a newline.
pub fn json(v: &Value) -> String {
    let mut out = String::new();
    write(v, 0, &mut out);
    out.push('\n');
    out
}

fn write(v: &Value, depth: usize, out: &mut String) {
    let pad = |d: usize| "  ".repeat(d);
    match v {
        Value::Object(map) if !map.is_empty() => {
            out.push_str("{\n");
            for (i, (k, x)) in map.iter().enumerate() {
                out.push_str(&pad(depth + 1));
                out.push_str(&Value::String(k.clone()).to_string());
                out.push_str(": ");
                write(x, depth + 1, out);
                if i + 1 < map.len() {
                    out.push(',');
                }
                out.push('\n');
            }
            out.push_str(&pad(depth));
            out.push('}');
        }
        Value::Array(items) if items.iter().any(|x| x.is_object() || x.is_array()) => {
            out.push_str("[\n");
            for (i, x) in items.iter().enumerate() {
                out.push_str(&pad(depth + 1));
                write(x, depth + 1, out);
                if i + 1 < items.len() {
                    out.push(',');
                }
                out.push('\n');
            }
            out.push_str(&pad(depth));
            out.push(']');
        }
        Value::Array(items) => {
            let parts: Vec<String> = items.iter().map(scalar).collect();
            out.push('[');
            out.push_str(&parts.join(", "));
            out.push(']');
        }
        other => out.push_str(&scalar(other)),
    }
}

/// A scalar's text; a whole `f64` below 2⁵³ without its `.0`.
fn scalar(v: &Value) -> String {
    match v.as_f64() {
        Some(x) if v.is_f64() && x.fract() == 0.0 && x.abs() < 9.007_199_254_740_992e15 => {
            format!("{x:.0}")
        }
        _ => v.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arrays_of_scalars_stay_on_one_line_and_round_trip() {
        let v = serde_json::json!({
            "a": [1, 2.5, null, 0.1, 1e300],
            "b": {"c": "x", "d": []},
            "e": [{"f": 1}],
            "g": {}
        });
        let text = json(&v);
        assert!(
            text.contains("\"a\": [1, 2.5, null, 0.1, 1e+300]"),
            "{text}"
        );
        let back: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(back, v);
        let whole = json(&serde_json::json!([1000.0, -3.0, 0.5]));
        assert_eq!(whole, "[1000, -3, 0.5]\n");
        let back: Vec<f64> = serde_json::from_str(&whole).unwrap();
        assert_eq!(back, [1000.0, -3.0, 0.5]);
    }
}
