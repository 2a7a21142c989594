//! Transfer function files: presets, tetvr's JSON format, ParaView import, errors.

use std::path::PathBuf;

use tetvr::TransferFunction;
use tetvr::tf::file::{TfFileError, load_tf, parse_tf_json, preset_names, save_tf_json};
use tetvr::tf::{ControlPoint, DEFAULT_MAX_OPACITY};

const PARAVIEW_EXAMPLE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/assets/tf/paraview-cool-to-warm.json"
);

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("tf_files");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// The error text for `json`, read as file `bad.json` on the range [0, 1].
fn error_of(json: &str) -> String {
    parse_tf_json(json, "bad.json", (0.0, 1.0), 1.0)
        .unwrap_err()
        .to_string()
}

#[test]
fn every_preset_loads_and_spans_the_data_range() {
    assert!(preset_names().len() >= 4);
    for &name in preset_names() {
        for range in [(0.0, 1.0), (-250.0, 1.0e5)] {
            let tf = load_tf(name, range, 0.5).unwrap();
            assert_eq!(tf.unit_distance(), 0.5, "{name}");
            let p = tf.points();
            assert_eq!((p[0].s, p[p.len() - 1].s), range, "{name}");
            // Something is visible somewhere: a preset is never fully transparent.
            assert!(p.iter().any(|c| c.opacity > 0.0), "{name}");
        }
    }
}

#[test]
fn viridis_preset_is_the_default_transfer_function() {
    for (lo, hi) in [(0.0, 1.0), (-3.5, 17.25), (1e-3, 2e-3), (3.0, 3.0)] {
        assert_eq!(
            load_tf("viridis", (lo, hi), 0.25).unwrap(),
            TransferFunction::default_for_range(lo, hi, 0.25).unwrap()
        );
    }
}

#[test]
fn saved_files_load_back_identically() {
    let path = scratch("round_trip.json");
    for tf in [
        TransferFunction::default_for_range(-1.25, 3.0e4, 0.125).unwrap(),
        load_tf("shock", (0.1, 0.7), 2.0 / 3.0).unwrap(),
        load_tf("cool-warm", (-1.0, 1.0), 1.0).unwrap(),
    ] {
        save_tf_json(&tf, &path).unwrap();
        // The file's unit distance wins over the default given here (a different value).
        let back = load_tf(path.to_str().unwrap(), (5.0, 6.0), 99.0).unwrap();
        assert_eq!(back, tf);
    }
}

/// Windows editors (Notepad) start UTF-8 files with a byte order mark; the file reads as
/// without one, as the mesh readers take it. Before, it failed with "line 1 column 1: not valid
/// JSON: expected value", which hid the cause.
#[test]
fn a_byte_order_mark_is_skipped() {
    let json = r#"{"points": [[0, 1, 0, 0, 0.5], [1, 0, 0, 1, 0.5]], "normalized": true}"#;
    let path = scratch("bom.json");
    std::fs::write(&path, format!("\u{feff}{json}")).unwrap();
    assert_eq!(
        load_tf(path.to_str().unwrap(), (2.0, 3.0), 1.0).unwrap(),
        parse_tf_json(json, "plain.json", (2.0, 3.0), 1.0).unwrap()
    );
}

#[test]
fn unit_distance_comes_from_the_file_or_the_default() {
    let with = r#"{"points": [[0, 0, 0, 0, 0], [10, 1, 1, 1, 0.5]], "unit_distance": 2.5}"#;
    let without = r#"{"points": [[0, 0, 0, 0, 0], [10, 1, 1, 1, 0.5]]}"#;
    let tf = parse_tf_json(with, "a.json", (0.0, 1.0), 7.0).unwrap();
    assert_eq!(tf.unit_distance(), 2.5);
    // Data units: the data range does not move the points of a non-normalized file.
    assert_eq!(tf.points()[1].s, 10.0);
    let tf = parse_tf_json(without, "b.json", (0.0, 1.0), 7.0).unwrap();
    assert_eq!(tf.unit_distance(), 7.0);
    // A CLI --unit-distance override replaces the file's value.
    assert_eq!(tf.with_unit_distance(0.5).unwrap().unit_distance(), 0.5);
    let normalized = r#"{"points": [[0, 0, 0, 0, 0], [0.25, 1, 1, 1, 0.5]], "normalized": true}"#;
    let tf = parse_tf_json(normalized, "c.json", (100.0, 200.0), 1.0).unwrap();
    assert_eq!(tf.points()[1].s, 125.0);
}

#[test]
fn paraview_cool_to_warm_is_rescaled_to_the_data_range() {
    let tf = load_tf(PARAVIEW_EXAMPLE, (10.0, 20.0), 1.0).unwrap();
    let p = tf.points();
    assert_eq!(
        p.iter().map(|c| c.s).collect::<Vec<_>>(),
        [10.0, 15.0, 20.0]
    );
    assert_eq!(p[0].color, [0.23137254902, 0.298039215686, 0.752941176471]);
    assert_eq!(p[1].color, [0.865; 3]);
    assert_eq!(
        p[2].color,
        [0.705882352941, 0.0156862745098, 0.149019607843]
    );
    assert_eq!(
        p.iter().map(|c| c.opacity).collect::<Vec<_>>(),
        [0.0, 0.5, 1.0]
    );
}

#[test]
fn paraview_lists_merge_and_missing_opacity_is_a_ramp() {
    // Colours over [-1, 1], opacity over [0, 4] with a point at 1 (a quarter of its range).
    let json = r#"[{"Name": "test", "RGBPoints": [-1, 0, 0, 0, 1, 1, 1, 1],
                   "Points": [0, 0, 0.5, 0, 1, 0.8, 0.5, 0, 4, 0.2, 0.5, 0]}]"#;
    let tf = parse_tf_json(json, "pv.json", (0.0, 100.0), 1.0).unwrap();
    let p = tf.points();
    assert_eq!(
        p.iter().map(|c| c.s).collect::<Vec<_>>(),
        [0.0, 25.0, 100.0]
    );
    assert_eq!(p[1].color, [0.25; 3]);
    assert_eq!(
        p.iter().map(|c| c.opacity).collect::<Vec<_>>(),
        [0.0, 0.8, 0.2]
    );
    let ramp = r#"[{"RGBPoints": [0, 0, 0, 0, 0.5, 1, 0, 0, 2, 1, 1, 1]}]"#;
    let tf = parse_tf_json(ramp, "pv.json", (0.0, 8.0), 1.0).unwrap();
    let expected = [(0.0, 0.0), (2.0, 0.25), (8.0, 1.0)];
    for (c, (s, u)) in tf.points().iter().zip(expected) {
        assert_eq!((c.s, c.opacity), (s, DEFAULT_MAX_OPACITY * u));
    }
    // A repeated x is a step: two points at the same s.
    let step = r#"[{"RGBPoints": [0, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1, 2, 1, 1, 1]}]"#;
    let tf = parse_tf_json(step, "pv.json", (0.0, 2.0), 1.0).unwrap();
    let at_one: Vec<&ControlPoint> = tf.points().iter().filter(|c| c.s == 1.0).collect();
    assert_eq!(at_one.len(), 2);
    assert_eq!((at_one[0].color, at_one[1].color), ([0.0; 3], [1.0; 3]));
}

#[test]
fn malformed_files_name_the_file_and_the_place() {
    let cases = [
        (
            r#"{"points": [[0, 0, 0, 0, 0], [1, 1, 1, 1, 1], [2, 1, 1, 1, 1], [3, 1, 1]]}"#,
            "bad.json: points[3]: expected 5 numbers [s, r, g, b, a]",
        ),
        (
            r#"{"points": [[0, 0, 1.5, 0, 0]]}"#,
            "bad.json: points[0]: colour or opacity 1.5 is outside [0, 1]",
        ),
        (
            r#"{"points": []}"#,
            "bad.json: points: expected a non-empty array",
        ),
        (r#"{"pts": []}"#, "bad.json: pts: unknown key"),
        (
            r#"{"normalized": true}"#,
            "bad.json: top level: missing \"points\"",
        ),
        (
            r#"{"points": [[0, 0, 0, 0, 0]], "unit_distance": -1}"#,
            "bad.json: unit_distance: expected a positive number",
        ),
        (
            r#"{"points": [[0, 0, 0, 0, 0]], "normalized": "yes"}"#,
            "bad.json: normalized: expected true or false",
        ),
        ("42", "bad.json: top level: expected an object"),
        ("[]", "bad.json: [0]: expected a ParaView colour map preset"),
        (
            r#"[{"IndexedColors": [1, 0, 0]}]"#,
            "bad.json: [0]: an indexed (categorical) colour map",
        ),
        (
            r#"[{"RGBPoints": [0, 0, 0, 0, 1, 1, 1]}]"#,
            "bad.json: [0].RGBPoints: expected a non-empty flat array of [x, r, g, b] repeated",
        ),
        (
            r#"[{"RGBPoints": [0, 0, 0, 0, 1, 1, 1, 1], "Points": [0, 0, 0.5, 0, 1, 2, 0.5, 0]}]"#,
            "bad.json: [0].Points[4]: value 2 is outside [0, 1]",
        ),
        (
            r#"[{"RGBPoints": [1, 0, 0, 0, 0, 1, 1, 1]}]"#,
            "bad.json: [0].RGBPoints[4]: x = 0 is smaller than the x before it",
        ),
        (
            r#"[{"RGBPoints": [0, 0, "a", 0]}]"#,
            "bad.json: [0].RGBPoints[0]: expected numbers",
        ),
        (
            "{\n  \"points\": [[0, 0, 0, 0, 0],\n}",
            "bad.json: line 3 column 1: not valid JSON",
        ),
    ];
    for (json, expected) in cases {
        let e = error_of(json);
        assert!(
            e.starts_with(expected),
            "{json}\n  gave: {e}\n  wanted: {expected}"
        );
    }
}

#[test]
fn unknown_specs_and_bad_ranges_are_errors() {
    let e = load_tf("no-such-preset", (0.0, 1.0), 1.0).unwrap_err();
    assert!(matches!(e, TfFileError::NotFound { .. }));
    let msg = e.to_string();
    assert!(preset_names().iter().all(|n| msg.contains(n)), "{msg}");
    let e = load_tf("viridis", (1.0, 0.0), 1.0).unwrap_err();
    assert!(matches!(e, TfFileError::BadDataRange { .. }), "{e}");
    let e = load_tf("viridis", (0.0, f64::INFINITY), 1.0).unwrap_err();
    assert!(matches!(e, TfFileError::BadDataRange { .. }), "{e}");
    // A range whose width overflows f64: said so, not "control point 0 is not finite".
    let e = load_tf("viridis", (-1.7e308, 1.7e308), 1.0).unwrap_err();
    assert!(matches!(e, TfFileError::RangeTooWide { .. }), "{e}");
    assert!(e.to_string().contains("rescale the array"), "{e}");
    let e = load_tf("viridis", (0.0, 1.0), 0.0).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("preset 'viridis': unit distance 0"),
        "{e}"
    );
    let dir = scratch("");
    let e = save_tf_json(
        &load_tf("grayscale", (0.0, 1.0), 1.0).unwrap(),
        dir.join("no/such/dir.json"),
    );
    assert!(e.unwrap_err().to_string().contains("no/such/dir.json"));
}

#[test]
fn presets_on_constant_data_put_the_value_inside_the_map() {
    // Every point on the one value made a step that the modes took from different sides:
    // cellproj and shells drew a constant field empty where the reference drew it. Widened, the
    // value lies strictly between distinct points, so no mode meets a step there.
    for value in [0.0, 3.5, -2e10, 1e300] {
        for name in preset_names() {
            let tf = load_tf(name, (value, value), 1.0).unwrap();
            let p = tf.points();
            let (first, last) = (p[0].s, p[p.len() - 1].s);
            assert!(
                first < value && value < last,
                "{name} at {value:e}: [{first:e}, {last:e}]"
            );
        }
        // The default preset's opacity ramps from 0: the value in the middle is visible.
        assert!(
            load_tf("viridis", (value, value), 1.0)
                .unwrap()
                .eval(value)
                .tau
                > 0.0
        );
    }
}
