mod common;
use anatomy::breast::Side;

#[test]
#[ignore]
fn clip_boxes() {
    let mut patients = vec![("phantom", common::phantom())];
    let scans: Vec<(&str, common::Patient)> = ["v02_average", "pair1_pre"]
        .iter()
        .filter_map(|n| Some((*n, common::shared_scan(n)?)))
        .collect();
    for (n, p) in &scans {
        patients.push((n, p));
    }
    for (name, p) in patients {
        let frame = p.frame();
        let cb = p.model.closed_surface.clip_box;
        let (lo, hi) = p
            .marked
            .scan
            .mesh
            .positions
            .iter()
            .map(|q| frame.to_local(*q))
            .fold(
                (glam::DVec3::splat(1e9), glam::DVec3::splat(-1e9)),
                |(a, b), q| (a.min(q), b.max(q)),
            );
        println!(
            "{name}: clip x {:.0}..{:.0} y {:.0}..{:.0}; scan x {:.0}..{:.0} y {:.0}..{:.0}",
            cb.x_min_mm, cb.x_max_mm, cb.y_min_mm, cb.y_max_mm, lo.x, hi.x, lo.y, hi.y
        );
        println!(
            "  slopes {:.3} {:.3} at y {:.0}; room {:?}; warnings {:?}",
            cb.x_min_slope,
            cb.x_max_slope,
            cb.y_ref_mm,
            p.model.closed_surface.lateral_room_mm,
            p.model.closed_surface.warnings
        );
        for name in ["PSMFll", "PSMFlr", "Pnl", "Pnr", "PSMFl", "PSMFr"] {
            let q = frame.to_local(
                p.landmarks()
                    .get(anatomy::LandmarkName::parse(name).unwrap()),
            );
            print!(" {name} {:.0?}", q);
        }
        println!();
        // scan width per 10 mm band of y
        let local: Vec<glam::DVec3> = p
            .marked
            .scan
            .mesh
            .positions
            .iter()
            .map(|q| frame.to_local(*q))
            .collect();
        let mut y = cb.y_min_mm - 20.0;
        while y < cb.y_max_mm + 10.0 {
            let (a, b) = local
                .iter()
                .filter(|q| q.y >= y && q.y < y + 10.0)
                .fold((1e9f64, -1e9f64), |(a, b), q| (a.min(q.x), b.max(q.x)));
            print!(" y{:.0}:{:.0}..{:.0}", y, a, b);
            y += 10.0;
        }
        println!();
        for side in Side::BOTH {
            let f = &p.model.breasts.breast(side).fill.mesh;
            let (lo, hi) = f.positions.iter().map(|q| frame.to_local(*q)).fold(
                (glam::DVec3::splat(1e9), glam::DVec3::splat(-1e9)),
                |(a, b), q| (a.min(q), b.max(q)),
            );
            let n = common::nipple(p.landmarks(), side);
            println!(
                "  {side}: fill x {:.0}..{:.0} y {:.0}..{:.0} z {:.0}..{:.0}; nipple {:.0?}; volume {:.0} ml",
                lo.x,
                hi.x,
                lo.y,
                hi.y,
                lo.z,
                hi.z,
                frame.to_local(n),
                p.model.breasts.breast(side).volume_ml
            );
        }
    }
}
