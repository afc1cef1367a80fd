//! Implant specs of the command-line contract.

use implant::{
    AnatomicImplant, AnatomicTaper, Catalog, ImplantError, ImplantShape, ImplantSpec, RoundImplant,
    RoundProfile, SpecError,
};

fn parse(s: &str) -> Result<ImplantSpec, SpecError> {
    s.parse()
}

#[test]
fn contract_examples_parse() {
    let round = parse("round:diameter=115,projection=33").unwrap();
    assert_eq!(
        round,
        ImplantSpec::Shape(RoundImplant::new(115.0, 33.0).unwrap().into())
    );
    let anatomic = parse("anatomic:width=120,height=113,projection=42").unwrap();
    assert_eq!(
        anatomic,
        ImplantSpec::Shape(AnatomicImplant::new(120.0, 113.0, 42.0).unwrap().into())
    );
    assert_eq!(
        parse("catalog:R-MOD-120").unwrap(),
        ImplantSpec::Catalog("R-MOD-120".into())
    );
    // Lenient spelling: case, spaces, `mm`, key order, a trailing comma.
    assert_eq!(
        parse(" Round: Projection = 33mm , DIAMETER=115.0, ").unwrap(),
        round
    );
}

#[test]
fn optional_keys_and_canonical_text() {
    let ImplantSpec::Shape(ImplantShape::Round(r)) =
        parse("round:diameter=115,projection=33,profile=smoothed").unwrap()
    else {
        panic!("not round")
    };
    assert_eq!(r.profile(), RoundProfile::Smoothed);
    let ImplantSpec::Shape(ImplantShape::Anatomic(a)) =
        parse("anatomic:width=120,height=113,projection=42,taper=Short").unwrap()
    else {
        panic!("not anatomic")
    };
    assert_eq!(a.taper(), AnatomicTaper::Short);
    // Display gives the canonical spec, and parsing it gives the spec back.
    for text in [
        "round:diameter=115,projection=33",
        "round:diameter=115,projection=33.5,profile=smoothed",
        "anatomic:width=120,height=113,projection=42",
        "anatomic:width=120,height=113,projection=42,taper=short",
        "anatomic:width=120,height=100,projection=30,taper=tall",
        "catalog:A-FF-120",
    ] {
        let spec = parse(text).unwrap();
        assert_eq!(spec.to_string(), text);
        assert_eq!(parse(&spec.to_string()).unwrap(), spec);
    }
    // A taper equal to the one chosen by height is not repeated.
    assert_eq!(
        parse("anatomic:width=120,height=113,projection=42,taper=tall")
            .unwrap()
            .to_string(),
        "anatomic:width=120,height=113,projection=42"
    );
}

#[test]
fn resolve_against_a_catalog() {
    let catalog = Catalog::builtin();
    let entry = parse("catalog:r-mod-120")
        .unwrap()
        .resolve(&catalog)
        .unwrap();
    assert_eq!(entry.id(), "R-MOD-120");
    let entry = parse("round:diameter=115,projection=33")
        .unwrap()
        .resolve(&catalog)
        .unwrap();
    assert_eq!(entry.id(), "round:diameter=115,projection=33");
    assert_eq!(entry.family(), "custom");
    assert!((entry.volume_ml() - 228.51).abs() < 0.01);

    let e = parse("catalog:R-MOD-12")
        .unwrap()
        .resolve(&catalog)
        .unwrap_err();
    assert!(matches!(e, SpecError::UnknownCatalogId { .. }), "{e}");
    let text = e.to_string();
    assert!(text.contains("unknown catalog id `R-MOD-12`"), "{text}");
    assert!(text.contains("did you mean R-MOD-120"), "{text}");
    let e = parse("catalog:nothing-like-it")
        .unwrap()
        .resolve(&catalog)
        .unwrap_err();
    assert!(!e.to_string().contains("did you mean"), "{e}");
    assert!(
        e.to_string()
            .contains(&format!("{} entries", catalog.len()))
    );
}

#[test]
fn bad_specs_say_what_is_wrong() {
    let cases: [(&str, &str); 14] = [
        ("115x33", "no `kind:` prefix"),
        ("oval:width=120", "unknown kind `oval`"),
        ("catalog:  ", "empty catalog id"),
        (
            "round:diameter=115,projection",
            "`projection` is not `key=value`",
        ),
        (
            "round:width=115,projection=33",
            "unknown key `width` for a round implant (allowed: diameter, projection, profile)",
        ),
        (
            "round:diameter=115",
            "missing `projection=` for a round implant",
        ),
        ("anatomic:width=120,projection=42", "missing `height=`"),
        (
            "round:diameter=115,diameter=120,projection=33",
            "key `diameter` given twice",
        ),
        (
            "round:diameter=11five,projection=33",
            "`diameter=11five`: expected a number of millimetres",
        ),
        (
            "round:diameter=,projection=33",
            "`diameter=`: expected a number",
        ),
        (
            "round:diameter=115,projection=33,profile=flat",
            "expected `ellipsoid` or `smoothed`",
        ),
        (
            "anatomic:width=120,height=113,projection=42,taper=x",
            "expected `tall` or `short`",
        ),
        (
            "round:diameter=0,projection=33",
            "diameter 0 mm is outside the accepted range",
        ),
        (
            "round:diameter=100,projection=60",
            "larger than half the diameter (50 mm)",
        ),
    ];
    for (text, expected) in cases {
        let e = parse(text).unwrap_err();
        let message = e.to_string();
        assert!(message.contains(expected), "{text}: {message}");
        assert!(
            message.contains(text.trim()),
            "{text}: the message quotes the spec: {message}"
        );
    }
    let e = parse("anatomic:width=120,height=-113,projection=42").unwrap_err();
    assert!(
        matches!(
            e,
            SpecError::Invalid {
                source: ImplantError::OutOfRange { what: "height", .. },
                ..
            }
        ),
        "{e}"
    );
    let e = parse("round:diameter=inf,projection=33").unwrap_err();
    assert!(
        matches!(
            e,
            SpecError::Invalid {
                source: ImplantError::NonFinite { .. },
                ..
            }
        ),
        "{e}"
    );
}
