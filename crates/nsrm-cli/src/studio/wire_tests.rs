//! The unit tests of `wire.rs`: every value the page sends is read, every flag value the CLI
//! takes is read alike, a bad value is refused naming the values allowed, and the answers' shape.

use super::*;
use clap::ValueEnum;
use serde_json::json;

/// The values of `<select id="ID">`'s options in the page (an option's `value`, else its text).
fn page_options(id: &str) -> Vec<String> {
    let html = include_str!("web/index.html");
    let start = html
        .find(&format!("<select id=\"{id}\">"))
        .unwrap_or_else(|| panic!("no select {id} in the page"));
    let body = &html[start..];
    let body = &body[..body.find("</select>").expect("the select's end")];
    body.split("<option")
        .skip(1)
        .map(|o| {
            let (attrs, rest) = o.split_once('>').expect("an option's tag");
            match attrs.split_once("value=\"") {
                Some((_, v)) => v[..v.find('"').expect("the value's end")].to_string(),
                None => rest[..rest.find("</option>").expect("the option's end")].to_string(),
            }
        })
        .collect()
}

fn fit_request(field: &str, value: &str) -> Result<FitRequest, String> {
    serde_json::from_value(json!({ field: value })).map_err(|e| e.to_string())
}

fn settings(field: &str, value: &str) -> Result<Settings, String> {
    serde_json::from_value(json!({ field: value })).map_err(|e| e.to_string())
}

#[test]
fn every_value_the_page_sends_is_read() {
    let kinds = page_options("kind");
    assert_eq!(kinds, ["lrm", "prm", "rprm", "nsrm"]);
    for v in &kinds {
        let r = fit_request("kind", v).unwrap();
        assert_eq!(r.kind.name_of(), *v);
    }
    let objectives = page_options("objective");
    assert!(objectives.len() >= 2, "{objectives:?}");
    for v in &objectives {
        let r = fit_request("objective", v).unwrap();
        assert_eq!(r.objective.name_of(), *v);
    }
    let ridges = page_options("ridge");
    assert!(ridges.len() >= 2, "{ridges:?}");
    for v in &ridges {
        let r = fit_request("ridge", v).unwrap();
        // The blank option is no ridge named.
        assert_eq!(r.ridge.map(|r| r.name_of()).unwrap_or_default(), *v);
    }
    let normalise = page_options("normalise");
    assert_eq!(normalise, ["raw", "white-balanced"]);
    for v in &normalise {
        let r = fit_request("normalise", v).unwrap();
        assert_eq!(r.normalise.name_of(), *v);
    }
    for v in page_options("order") {
        let r: FitRequest =
            serde_json::from_value(json!({ "order": v.parse::<u8>().unwrap() })).unwrap();
        assert_eq!(r.order.to_string(), v);
    }
    let charts = page_options("chart");
    assert_eq!(charts.len(), ChartKind::ALL.len(), "{charts:?}");
    for v in &charts {
        let s = settings("chart", v).unwrap();
        assert_eq!(s.chart.name_of(), *v);
    }
    // The flat fields the page offers: its own options, a listed file's (`file:N`, added by
    // app.js) and the uploaded flat frame's.
    let mut flats = page_options("flat");
    flats.extend(["file:0".to_string(), "file:12".into(), "upload".into()]);
    for v in &flats {
        let s = settings("flat", v).unwrap();
        assert_eq!(s.flat.map(|f| f.name_of()).as_ref(), Some(v));
    }
    // The page sends the settings of an answer back: they read as they were.
    let all = json!({
        "chart": "spyder24", "reference": null, "reference_white": "D50",
        "corners": [[1.5, 2.0], [3.0, 4.0], [5.0, 6.0], [7.0, 8.25]],
        "exclude": ["A1"], "flat": "file:1", "white_level": 0.5, "layer": null,
    });
    let s: Settings = serde_json::from_value(all.clone()).unwrap();
    assert_eq!(serde_json::to_value(&s).unwrap(), all);
    assert_eq!(
        serde_json::to_value(Settings::default()).unwrap(),
        json!({
            "chart": "cc24", "reference": null, "reference_white": null, "corners": null,
            "exclude": [], "flat": null, "white_level": null, "layer": null,
        })
    );
}

/// Every name and alias clap takes for a variant of `T` (and the same in capitals: the CLI's
/// flags ignore case) is read as that variant.
fn clap_names_read<T: ValueEnum + PartialEq + std::fmt::Debug>(read: impl Fn(&str) -> T) {
    for v in T::value_variants() {
        let p = v.to_possible_value().expect("no variant is skipped");
        for n in p.get_name_and_aliases() {
            assert_eq!(&read(n), v, "{n}");
            assert_eq!(&read(&n.to_ascii_uppercase()), v, "{n}");
        }
    }
}

#[test]
fn every_flag_value_is_read_as_the_cli_reads_it() {
    clap_names_read(|n| fit_request("kind", n).unwrap().kind);
    clap_names_read(|n| fit_request("normalise", n).unwrap().normalise);
    clap_names_read(|n| settings("chart", n).unwrap().chart);
    for (text, want) in [
        ("ls", Objective::LeastSquares),
        ("de00", Objective::De00 { power: 2.0 }),
        ("DE00:4", Objective::De00 { power: 4.0 }),
    ] {
        assert_eq!(fit_request("objective", text).unwrap().objective, want);
    }
    for (text, want) in [
        ("", None),
        ("  ", None),
        ("0", Some(Ridge::None)),
        ("1e-3", Some(Ridge::Lambda(1e-3))),
        ("auto", Some(Ridge::Auto)),
        ("auto-gcv", Some(Ridge::Auto)),
        ("AUTO-LOO", Some(Ridge::AutoLoo)),
    ] {
        let r = fit_request("ridge", text).unwrap().ridge;
        assert_eq!(r, want, "{text}");
        // Its name reads back as the same value.
        if let Some(r) = r {
            assert_eq!(Ridge::parse(&r.name_of()).unwrap(), r);
        }
    }
    let r: FitRequest = serde_json::from_value(json!({})).unwrap();
    assert_eq!(
        (r.kind, r.order, r.objective, r.ridge, r.normalise),
        (Kind::Nsrm, 3, Objective::LeastSquares, None, Normalise::Raw)
    );
    assert_eq!(settings("flat", "").unwrap().flat, None);
    assert_eq!(
        settings("flat", "NEUTRALS").unwrap().flat,
        Some(Flat::Neutrals)
    );
}

#[test]
fn a_bad_value_is_refused_naming_the_values_allowed() {
    for (field, value, allowed) in [
        ("kind", "xyz", "lrm, prm, rprm or nsrm"),
        ("normalise", "nope", "raw or white-balanced"),
        ("objective", "de00:1", "ls, de00 or de00:P"),
        ("ridge", "-1", "auto (GCV), auto-loo or a number"),
    ] {
        let e = fit_request(field, value).unwrap_err();
        assert!(e.contains(value) && e.contains(allowed), "{field}: {e}");
    }
    for (field, value, allowed) in [
        ("chart", "auto", "cc24, sg, spyder24"),
        ("flat", "/etc/passwd", "none, neutrals, file:N"),
        ("flat", "file:x", "none, neutrals, file:N"),
    ] {
        let e = settings(field, value).unwrap_err();
        assert!(e.contains(value) && e.contains(allowed), "{field}: {e}");
    }
    // Not a name at all.
    let e = serde_json::from_value::<FitRequest>(json!({"kind": 3})).unwrap_err();
    assert!(e.to_string().contains("expected a string"), "{e}");
    let e = serde_json::from_value::<FitRequest>(json!({"normalise": null})).unwrap_err();
    assert!(e.to_string().contains("expected a string"), "{e}");
}

#[test]
fn answers_have_the_page_s_field_names() {
    assert_eq!(
        serde_json::to_value(ErrorBody { error: "x".into() }).unwrap(),
        json!({"error": "x"})
    );
    assert_eq!(
        serde_json::to_value(Closed { closed: "f1" }).unwrap(),
        json!({"closed": "f1"})
    );
    let failed = Evaluated::Failed {
        model: "prm".into(),
        order: 4,
        error: "why".into(),
    };
    assert_eq!(
        serde_json::to_value(failed).unwrap(),
        json!({"model": "prm", "order": 4, "error": "why"})
    );
    let p = PatchFit {
        label: "A1".into(),
        rgb: [1.0, 2.0, 3.0],
        reference_xyz: [4.0, 5.0, 6.0],
        corrected_xyz: [7.0, 8.0, 9.0],
        reference_srgb8: [1, 2, 3],
        corrected_srgb8: [4, 5, 6],
        de00: 0.5,
    };
    let v = serde_json::to_value(p).unwrap();
    assert_eq!(v["dE00"], json!(0.5));
    assert_eq!(v.as_object().unwrap().len(), 7);
}
