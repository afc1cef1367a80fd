//! `mammaplan catalog` as users and scripts see it: listing, suggesting, and clean
//! failures.

mod common;

use common::*;

#[test]
fn catalog_lists_and_suggests() {
    let list = mammaplan(&["catalog", "list", "--json"]);
    assert!(list.status.success(), "{}", stderr(&list));
    let listing: serde_json::Value = serde_json::from_slice(&list.stdout).unwrap();
    let entries = listing["entries"].as_array().unwrap();
    assert!(entries.len() >= 50, "{} entries", entries.len());
    for entry in entries {
        let volume = entry["volume_ml"].as_f64().unwrap();
        assert!((100.0..=800.0).contains(&volume), "{entry}");
    }

    // A round 120 x 33.5 mm implant is in the moderate family: it is its own best match.
    let suggest = mammaplan(&[
        "catalog",
        "suggest",
        "--width",
        "120",
        "--projection",
        "33.5",
        "--shape",
        "round",
        "--json",
    ]);
    assert!(suggest.status.success(), "{}", stderr(&suggest));
    let report: serde_json::Value = serde_json::from_slice(&suggest.stdout).unwrap();
    let best = &report["suggestions"][0];
    assert_eq!(best["id"], "R-MOD-120", "{report}");
    assert_eq!(best["distance_mm"].as_f64(), Some(0.0));

    // By volume: signed differences (entry minus target), closest first.
    let by_volume = mammaplan(&["catalog", "suggest", "--volume-ml", "300", "--json"]);
    assert!(by_volume.status.success(), "{}", stderr(&by_volume));
    let report: serde_json::Value = serde_json::from_slice(&by_volume.stdout).unwrap();
    let differences: Vec<f64> = report["suggestions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["volume_difference_ml"].as_f64().unwrap().abs())
        .collect();
    assert_eq!(differences.len(), 5);
    assert!(
        differences.windows(2).all(|w| w[0] <= w[1]),
        "{differences:?}"
    );
}

#[test]
fn bad_catalog_input_fails_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("catalog.csv");
    std::fs::write(
        &csv,
        "id,shape,family,width_mm,height_mm,projection_mm\nX1,round,test,120,,abc\n",
    )
    .unwrap();
    let csv = csv.to_str().unwrap();
    assert_clean_failure(&mammaplan(&["catalog", "list", "--catalog", csv]), "line 2");
    assert_clean_failure(
        &mammaplan(&[
            "catalog",
            "suggest",
            "--width",
            "1000",
            "--projection",
            "30",
        ]),
        "width_mm must be from 50 to 250",
    );
    assert_clean_failure(
        &mammaplan(&["catalog", "suggest", "--width", "120"]),
        "--projection",
    );
}
