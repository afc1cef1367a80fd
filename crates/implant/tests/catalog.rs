//! The built-in catalog, CSV catalogs and suggestions.

use implant::catalog::{
    ANATOMIC_FAMILIES, BUILTIN_VOLUME_RANGE_ML, BUILTIN_WIDTHS_MM, PROJECTION_WEIGHT,
    ROUND_FAMILIES,
};
use implant::{
    AnatomicTaper, Catalog, CatalogEntry, CatalogError, ImplantError, ImplantShape, RoundImplant,
    ShapeKind, SuggestTarget,
};
use std::collections::HashSet;
use std::f64::consts::PI;

fn read(text: &str) -> Result<Catalog, CatalogError> {
    Catalog::from_csv_reader(text.as_bytes(), "test.csv")
}

#[test]
fn builtin_catalog_covers_the_families_within_the_volume_range() {
    let catalog = Catalog::builtin();
    let (v_min, v_max) = BUILTIN_VOLUME_RANGE_ML;
    let ids: HashSet<&str> = catalog.entries().iter().map(|e| e.id()).collect();
    assert_eq!(ids.len(), catalog.len(), "ids are unique");
    for e in catalog.entries() {
        assert!(
            (v_min..=v_max).contains(&e.volume_ml()),
            "{}: {} ml",
            e.id(),
            e.volume_ml()
        );
        assert_eq!(e.volume_ml(), e.shape().volume_ml());
    }
    // Round entries: present exactly when the half-ellipsoid volume is within range.
    for (code, family, ratio) in ROUND_FAMILIES {
        for w in BUILTIN_WIDTHS_MM {
            let p = (w * ratio * 2.0).round() / 2.0;
            let v = PI * w * w * p / 6.0 / 1000.0;
            let id = format!("R-{code}-{w}");
            let entry = catalog.get(&id);
            assert_eq!(
                entry.is_some(),
                (v_min..=v_max).contains(&v),
                "{id}: {v} ml"
            );
            if let Some(e) = entry {
                assert_eq!(e.family(), family);
                assert_eq!((e.shape().width_mm(), e.shape().projection_mm()), (w, p));
                assert!((e.volume_ml() - v).abs() < 1e-9);
            }
        }
    }
    for (code, family, _, _) in ANATOMIC_FAMILIES {
        let members: Vec<&CatalogEntry> = catalog
            .entries()
            .iter()
            .filter(|e| e.id().starts_with(&format!("A-{code}-")))
            .collect();
        assert!(members.len() >= 8, "{code}: {} entries", members.len());
        assert!(members.iter().all(|e| e.family() == family));
        // Larger width, larger volume within a family.
        assert!(
            members
                .windows(2)
                .all(|p| p[0].volume_ml() < p[1].volume_ml())
        );
    }
    // Something was dropped at both ends.
    assert!(catalog.get("R-LOW-90").is_none() && catalog.get("R-XHIGH-160").is_none());
    let count = |kind| {
        catalog
            .entries()
            .iter()
            .filter(|e| e.shape().kind() == kind)
            .count()
    };
    assert!(count(ShapeKind::Round) >= 50 && count(ShapeKind::Anatomic) >= 40);
    // Both anatomic tapers are used.
    let tapers: HashSet<AnatomicTaper> = catalog
        .entries()
        .iter()
        .filter_map(|e| match e.shape() {
            ImplantShape::Anatomic(a) => Some(a.taper()),
            _ => None,
        })
        .collect();
    assert_eq!(tapers.len(), 2);
    let e = catalog.get("R-MOD-120").unwrap();
    assert_eq!(e.shape().projection_mm(), 33.5);
    println!(
        "builtin: {} round, {} anatomic",
        count(ShapeKind::Round),
        count(ShapeKind::Anatomic)
    );
    for id in [
        "R-LOW-100",
        "R-MOD-115",
        "R-HIGH-120",
        "R-XHIGH-155",
        "A-FF-120",
        "A-LM-105",
    ] {
        let e = catalog.get(id).unwrap();
        println!("{id}: {} -> {:.1} ml", e.shape(), e.volume_ml());
    }
}

#[test]
fn entries_serialise_for_the_command_line() {
    let catalog = Catalog::builtin();
    let json = serde_json::to_value(catalog.get("A-FF-120").unwrap()).unwrap();
    assert_eq!(json["id"], "A-FF-120");
    assert_eq!(json["shape"], "anatomic");
    assert_eq!(json["family"], "full height full projection");
    assert_eq!(json["width_mm"], 120.0);
    assert_eq!(json["height_mm"], 114.0);
    assert_eq!(json["projection_mm"], 42.0);
    assert_eq!(json["variant"], "tall");
    assert!(json["volume_ml"].as_f64().unwrap() > 200.0);
    assert!(json["max_thickness_mm"].as_f64().unwrap() < 42.0);
    let json = serde_json::to_value(catalog.get("R-MOD-120").unwrap()).unwrap();
    assert_eq!(json["height_mm"], json["width_mm"]);
    assert_eq!(json["variant"], "ellipsoid");
    let all = serde_json::to_string(catalog.entries()).unwrap();
    assert!(all.starts_with("[{\"id\":\"R-LOW-100\""), "{}", &all[..40]);
}

#[test]
fn lookup_is_exact_then_case_insensitive() {
    let catalog = Catalog::builtin();
    assert_eq!(catalog.get("r-mod-120").unwrap().id(), "R-MOD-120");
    assert_eq!(catalog.get(" R-MOD-120 ").unwrap().id(), "R-MOD-120");
    assert!(catalog.get("R-MOD-121").is_none());
}

const GOOD_CSV: &str = "\u{feff}ID, Shape, family, width_mm, height_mm, projection_mm, volume_ml\n\
# a manufacturer's table, nominal volumes ignored\n\
X-1,round,\"smooth, moderate\",115,,33,250\n\
\n\
X-2, anatomic, full height, 120, 113, 42, 280\n\
X-3, ROUND, , 100, 100, 30, 160\n";

#[test]
fn csv_catalog_is_read_with_computed_volumes() {
    let catalog = read(GOOD_CSV).unwrap();
    assert_eq!(catalog.len(), 3);
    let x1 = catalog.get("X-1").unwrap();
    assert_eq!(x1.family(), "smooth, moderate");
    assert_eq!(
        x1.shape(),
        &ImplantShape::from(RoundImplant::new(115.0, 33.0).unwrap())
    );
    assert!((x1.volume_ml() - 228.51).abs() < 0.01);
    let x2 = catalog.get("X-2").unwrap();
    assert_eq!(x2.shape().kind(), ShapeKind::Anatomic);
    assert!((x2.volume_ml() - 216.74).abs() < 0.01);
    assert_eq!(catalog.get("X-3").unwrap().family(), "");

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cat.csv");
    std::fs::write(&path, GOOD_CSV).unwrap();
    assert_eq!(Catalog::load_csv(&path).unwrap(), catalog);
    let missing = dir.path().join("missing.csv");
    let e = Catalog::load_csv(&missing).unwrap_err();
    assert!(matches!(e, CatalogError::Io { .. }), "{e}");
    assert!(e.to_string().contains("missing.csv"), "{e}");
}

/// (CSV text, expected line, expected column name) for cell errors.
#[test]
fn csv_errors_name_the_line_and_column() {
    let header = "id,shape,family,width_mm,height_mm,projection_mm\n";
    let cases = [
        (
            "A,round,f,11x5,,33\n",
            2,
            "width_mm",
            "expected a number of millimetres, got `11x5`",
        ),
        (
            "A,round,f,115,,33\nB,oval,f,115,,33\n",
            3,
            "shape",
            "expected `round` or `anatomic`",
        ),
        (",round,f,115,,33\n", 2, "id", "every implant needs an id"),
        ("A,round,f,115,,\n", 2, "projection_mm", "empty"),
        ("A,anatomic,f,120,,42\n", 2, "height_mm", "needs a height"),
        (
            "A,round,f,115,120,33\n",
            2,
            "height_mm",
            "equal to its width",
        ),
        (
            "A,round,f,115,,70\n",
            2,
            "projection_mm",
            "larger than half the diameter",
        ),
        (
            "A,round,f,-115,,30\n",
            2,
            "width_mm",
            "outside the accepted range",
        ),
        (
            "A,anatomic,f,120,0,30\n",
            2,
            "height_mm",
            "outside the accepted range",
        ),
        ("A,round,f,NaN,,30\n", 2, "width_mm", "not a finite number"),
        (
            "A,round,f,115,,33\n\n\nB,round,f,115\n",
            5,
            "projection_mm",
            "empty",
        ),
    ];
    for (rows, line, column, text) in cases {
        let e = read(&format!("{header}{rows}")).unwrap_err();
        match &e {
            CatalogError::Field {
                line: l,
                column: c,
                column_index,
                source_name,
                ..
            } => {
                assert_eq!((*l, c.as_str()), (line, column), "{e}");
                assert_eq!(source_name, "test.csv");
                let expected_index =
                    1 + header.trim().split(',').position(|h| h == column).unwrap();
                assert_eq!(*column_index, expected_index);
            }
            other => panic!("{rows:?}: expected a field error, got {other}"),
        }
        let message = e.to_string();
        assert!(message.contains(text), "{message}");
        assert!(
            message.starts_with(&format!("test.csv: line {line}, column ")),
            "{message}"
        );
    }
}

#[test]
fn csv_structure_errors() {
    let e = read("id,shape,width_mm,projection_mm\nA,round,115,33\n").unwrap_err();
    assert!(matches!(e, CatalogError::Header { line: 1, .. }), "{e}");
    assert!(e.to_string().contains("missing column `family`"), "{e}");
    let e = read("id,shape,family,width_mm,width_mm,projection_mm\n").unwrap_err();
    assert!(e.to_string().contains("`width_mm` appears twice"), "{e}");
    let e = read("id,shape,family,width_mm,projection_mm\nA,anatomic,f,120,42\n").unwrap_err();
    assert!(matches!(e, CatalogError::Row { line: 2, .. }), "{e}");
    assert!(e.to_string().contains("no `height_mm` column"), "{e}");
    let e = read("id,shape,family,width_mm,projection_mm\nA,round,f,115,33\nA,round,g,120,33\n")
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "test.csv: line 3: id `A` already used on line 2"
    );
    assert!(matches!(read(""), Err(CatalogError::Empty { .. })));
    let e = read("id,shape,family,width_mm,projection_mm\n# nothing\n").unwrap_err();
    assert_eq!(e.to_string(), "test.csv: the catalog has no implant rows");
    let e = read("id,shape,family,width_mm,projection_mm\nA,round,\"f,115,33\n").unwrap_err();
    assert!(
        matches!(e, CatalogError::Field { .. } | CatalogError::Row { .. }),
        "{e}"
    );
    let bad_utf8: &[u8] = b"id,shape,family,width_mm,projection_mm\nA,round,\xff,115,33\n";
    let e = Catalog::from_csv_reader(bad_utf8, "test.csv").unwrap_err();
    assert!(matches!(e, CatalogError::Row { line: 2, .. }), "{e}");
}

#[test]
fn suggestions_by_dimensions() {
    let catalog = Catalog::builtin();
    // The exact dimensions of an entry find that entry first, at distance zero.
    let target = SuggestTarget::Dimensions {
        width_mm: 120.0,
        height_mm: Some(114.0),
        projection_mm: 42.0,
    };
    let s = catalog.suggest(&target, None, 5).unwrap();
    assert_eq!(s.len(), 5);
    assert_eq!(s[0].entry.id(), "A-FF-120");
    assert_eq!(s[0].distance_mm, Some(0.0));
    assert_eq!(s[0].volume_difference_ml, Some(0.0));
    assert!(s.windows(2).all(|p| p[0].distance_mm <= p[1].distance_mm));
    // The distance is the documented weighted one.
    for sug in &s {
        let e = sug.entry.shape();
        let d = ((e.width_mm() - 120.0).powi(2)
            + (e.height_mm() - 114.0).powi(2)
            + (PROJECTION_WEIGHT * (e.projection_mm() - 42.0)).powi(2))
        .sqrt();
        assert!((sug.distance_mm.unwrap() - d).abs() < 1e-12);
    }
    // The paper's round implant, round only, no height: the moderate family at 115 mm.
    let target = SuggestTarget::Dimensions {
        width_mm: 115.0,
        height_mm: None,
        projection_mm: 33.0,
    };
    let s = catalog.suggest(&target, Some(ShapeKind::Round), 3).unwrap();
    assert_eq!(s[0].entry.id(), "R-MOD-115");
    assert!(s.iter().all(|x| x.entry.shape().kind() == ShapeKind::Round));
    let json = serde_json::to_value(&s[0]).unwrap();
    assert_eq!(json["id"], "R-MOD-115");
    // R-MOD-115 has projection 32 (0.28 x 115 rounded to 0.5 mm): distance 2 x 1 mm,
    // volume π 115² (32 - 33) / 6 mm³ against the target's shape.
    assert_eq!(json["distance_mm"], 2.0);
    let dv = json["volume_difference_ml"].as_f64().unwrap();
    assert!(
        (dv + PI * 115.0 * 115.0 / 6.0 / 1000.0).abs() < 1e-9,
        "{dv}"
    );
    // More than the catalog holds: all of them.
    let all = catalog.suggest(&target, None, 10_000).unwrap();
    assert_eq!(all.len(), catalog.len());
}

#[test]
fn suggestions_by_volume() {
    let catalog = Catalog::builtin();
    let target = SuggestTarget::Volume { volume_ml: 250.0 };
    let s = catalog.suggest(&target, None, 4).unwrap();
    let best = catalog
        .entries()
        .iter()
        .map(|e| (e.volume_ml() - 250.0).abs())
        .fold(f64::INFINITY, f64::min);
    assert_eq!(s[0].volume_difference_ml.unwrap().abs(), best);
    assert!(best < 10.0, "{best}");
    assert!(s.windows(2).all(|p| {
        p[0].volume_difference_ml.unwrap().abs() <= p[1].volume_difference_ml.unwrap().abs()
    }));
    assert!(s.iter().all(|x| x.distance_mm.is_none()));
    let json = serde_json::to_value(&s[0]).unwrap();
    assert!(json.get("distance_mm").is_none());
    let s = catalog
        .suggest(&target, Some(ShapeKind::Anatomic), 2)
        .unwrap();
    assert!(
        s.iter()
            .all(|x| x.entry.shape().kind() == ShapeKind::Anatomic)
    );
}

#[test]
fn bad_suggestion_targets_are_rejected() {
    let catalog = Catalog::builtin();
    // Non-positive, not finite, or no implant's size (5 m, 5 litres).
    for bad in [0.0, -250.0, f64::NAN, f64::INFINITY, 5000.0] {
        let e = catalog
            .suggest(&SuggestTarget::Volume { volume_ml: bad }, None, 3)
            .unwrap_err();
        assert!(
            matches!(
                e,
                ImplantError::BadTarget {
                    what: "volume_ml",
                    ..
                }
            ),
            "{e}"
        );
        let target = SuggestTarget::Dimensions {
            width_mm: 120.0,
            height_mm: Some(bad),
            projection_mm: 40.0,
        };
        let e = catalog.suggest(&target, None, 3).unwrap_err();
        assert!(
            matches!(
                e,
                ImplantError::BadTarget {
                    what: "height_mm",
                    ..
                }
            ),
            "{e}"
        );
    }
}

#[test]
fn from_entries_rejects_duplicate_ids() {
    let shape = ImplantShape::from(RoundImplant::new(115.0, 33.0).unwrap());
    let a = CatalogEntry::new("A", "f", shape);
    assert_eq!(Catalog::from_entries(vec![a.clone()]).unwrap().len(), 1);
    let e = Catalog::from_entries(vec![a.clone(), a]).unwrap_err();
    assert!(
        matches!(
            e,
            CatalogError::DuplicateId {
                line: 2,
                first_line: 1,
                ..
            }
        ),
        "{e}"
    );
}
