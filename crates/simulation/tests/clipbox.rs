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
