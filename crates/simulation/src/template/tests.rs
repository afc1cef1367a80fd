use super::*;
use tetra::quality::signed_volume;

/// Side of the fixture's grid squares (mm).
const SQUARE_MM: f64 = 6.0;
/// Squares along each side of the fixture's grid, centred on the implant.
const SQUARES: usize = 12;
/// Heights of the fixture's vertex layers over the bed (mm): one behind it, two in front.
const LAYERS_MM: [f64; 3] = [-3.0, 3.0, 9.0];

/// A tetrahedron far from the slab, first in [`slab`]'s mesh and no candidate, so that
/// mesh and candidate numbers of vertices and elements differ (the template reads both).
const OUTLIER: [DVec3; 4] = [
    DVec3::new(500.0, 0.0, 100.0),
    DVec3::new(510.0, 0.0, 100.0),
    DVec3::new(500.0, 10.0, 100.0),
    DVec3::new(500.0, 0.0, 110.0),
];

/// A slab of tissue over the flat bed `z = 0`: a 72 x 72 mm grid centred on the anchor,
/// each square split into two triangles and each triangle's prism between neighbouring
/// layers into three positively oriented tetrahedra (the same split in every prism, so
/// neighbouring rows do not share faces: only the template's per-element rules read the
/// mesh here, no solver). Every slab vertex is a candidate with its foot straight below
/// it; the mesh starts with [`OUTLIER`]. Returns the mesh, its candidates and their feet.
fn slab() -> (TetMesh, SideCandidates, BedFeet) {
    slab_along(DVec3::Z)
}

/// [`slab`] with its layers laid off along the unit `normal` instead of `z`: the vertex
/// over bed point `(x, y, 0)` at height `h` lies at `(x, y, 0) + h normal`, and its foot
/// has that normal.
fn slab_along(normal: DVec3) -> (TetMesh, SideCandidates, BedFeet) {
    let n = SQUARES;
    let index = |i: usize, j: usize, layer: usize| ((layer * (n + 1) + i) * (n + 1) + j) as u32;
    let mut grid = vec![DVec3::ZERO; (n + 1) * (n + 1) * LAYERS_MM.len()];
    for (layer, &z) in LAYERS_MM.iter().enumerate() {
        for i in 0..=n {
            for j in 0..=n {
                let half = 0.5 * SQUARE_MM * n as f64;
                let (x, y) = (SQUARE_MM * i as f64 - half, SQUARE_MM * j as f64 - half);
                grid[index(i, j, layer) as usize] = DVec3::new(x, y, 0.0) + normal * z;
            }
        }
    }
    // in the grid's numbering, which is the candidates'
    let mut grid_tets = Vec::new();
    for layer in 0..LAYERS_MM.len() - 1 {
        for i in 0..n {
            for j in 0..n {
                for triangle in [
                    [(i, j), (i + 1, j), (i, j + 1)],
                    [(i + 1, j), (i + 1, j + 1), (i, j + 1)],
                ] {
                    let b = triangle.map(|(a, c)| index(a, c, layer));
                    let t = triangle.map(|(a, c)| index(a, c, layer + 1));
                    for mut tet in [
                        [b[0], b[1], b[2], t[0]],
                        [b[1], b[2], t[0], t[1]],
                        [b[2], t[0], t[1], t[2]],
                    ] {
                        if signed_volume(tet.map(|v| grid[v as usize])) < 0.0 {
                            tet.swap(0, 1);
                        }
                        grid_tets.push(tet);
                    }
                }
            }
        }
    }
    let first = OUTLIER.len() as u32;
    let mesh = TetMesh {
        positions: [&OUTLIER[..], &grid].concat(),
        tets: (std::iter::once([0, 1, 2, 3]))
            .chain(grid_tets.iter().map(|tet| tet.map(|v| v + first)))
            .collect(),
    };
    let feet = BedFeet {
        side: Side::Left,
        feet: (grid.iter())
            .map(|p| {
                let height_mm = p.z / normal.z;
                let position = *p - normal * height_mm;
                Some(Foot {
                    uv: position.truncate(),
                    height_mm,
                    normal,
                    position,
                })
            })
            .collect(),
    };
    let candidates = SideCandidates {
        vertices: (first..first + grid.len() as u32).collect(),
        positions: grid,
        tets: (grid_tets.iter().enumerate())
            .map(|(t, &tet)| (t as u32 + 1, tet))
            .collect(),
    };
    (mesh, candidates, feet)
}

/// A planned fold far below [`slab`], which bounds nothing.
const FOLD_BELOW_THE_SLAB: FoldPlane = FoldPlane {
    point: DVec3::new(0.0, -1000.0, 0.0),
    up: DVec3::Y,
    taper_mm: SQUARE_MM,
};

/// The template of a 50 mm round implant of 8 mm projection on [`slab`], with a layer
/// reaching the top vertices and `slides` as given.
fn slab_template(slides: Option<&[bool]>, on_wall: &[bool]) -> ImplantTemplate {
    slab_template_over(slides, on_wall, FOLD_BELOW_THE_SLAB)
}

/// [`slab_template`] over the planned `fold`.
fn slab_template_over(
    slides: Option<&[bool]>,
    on_wall: &[bool],
    fold: FoldPlane,
) -> ImplantTemplate {
    let (mesh, candidates, feet) = slab();
    let shape = ImplantShape::from(implant::RoundImplant::new(50.0, 8.0).unwrap());
    let rules = TemplateRules {
        hold_bed: true,
        layer_mm: 10.0,
        on_wall,
        slides,
        fold,
    };
    let thickness = SmoothedThickness::new(shape, 0.0);
    build_template(
        &mesh,
        &candidates,
        &feet,
        &Anchor::flat(),
        &thickness,
        &rules,
    )
    .unwrap()
}

/// The pushed vertices of `template` with their displacements, by vertex.
fn pushed_by_vertex(template: &ImplantTemplate) -> Vec<(u32, DVec3)> {
    let mut pushed: Vec<(u32, DVec3)> = template.pushed_vertices().copied().collect();
    pushed.sort_unstable_by_key(|&(v, _)| v);
    pushed
}

/// `slides: Some` with no vertex on the skin is `None`: the same template, field by
/// field and bit for bit (nothing slides, so nothing else may differ).
#[test]
fn sliding_with_no_skin_is_holding() {
    let count = slab().0.positions.len();
    let on_wall = vec![false; count];
    let held = slab_template(None, &on_wall);
    assert!(!held.implant_vertices.is_empty() && !held.implant_elements.is_empty());
    assert_eq!(slab_template(Some(&vec![false; count]), &on_wall), held);
}

/// Where nothing folds, as on this slab, sliding skin only changes which pushed vertices
/// are held. The skin here is the top layer and, from x = 12 mm on, the middle one (where
/// tissue thins to the side; the template reads only the mask), and one skin vertex over
/// the footprint is on the wall.
/// Against the held template:
/// - the pushed vertices and their displacements are the same, bit for bit: the same
///   displacements enter the scaling to the covered volume, so the factor is the same;
/// - the sliding ones are exactly the pushed skin vertices off the wall;
/// - the implant elements split into those with no sliding corner and the sliding ones.
#[test]
fn sliding_skin_moves_the_same_vertices_by_the_same_amount() {
    let (mesh, ..) = slab();
    let on_skin: Vec<bool> = (mesh.positions.iter())
        .map(|p| p.z == LAYERS_MM[2] || (p.z == LAYERS_MM[1] && p.x >= 12.0))
        .collect();
    let walled = (mesh.positions.iter())
        .position(|p| *p == DVec3::new(12.0, 0.0, LAYERS_MM[1]))
        .unwrap();
    let mut on_wall = vec![false; mesh.positions.len()];
    on_wall[walled] = true;
    let held = slab_template(None, &on_wall);
    let sliding = slab_template(Some(&on_skin), &on_wall);

    assert_eq!(pushed_by_vertex(&sliding), pushed_by_vertex(&held));
    assert_eq!(sliding.scale, held.scale);
    assert_eq!(sliding.template_volume_ml, held.template_volume_ml);
    assert_eq!(sliding.covered_volume_ml, held.covered_volume_ml);
    assert_eq!(sliding.fixed_vertices, held.fixed_vertices);

    let slides = |v: u32| on_skin[v as usize] && !on_wall[v as usize];
    let mut expected_skin: Vec<u32> = (held.implant_vertices.iter())
        .map(|&(v, _)| v)
        .filter(|&v| slides(v))
        .collect();
    expected_skin.sort_unstable();
    let mut skin: Vec<u32> = sliding.skin_vertices.iter().map(|&(v, _)| v).collect();
    skin.sort_unstable();
    assert!(!skin.is_empty());
    assert_eq!(skin, expected_skin);
    assert!(
        sliding
            .implant_vertices
            .iter()
            .any(|&(v, _)| v as usize == walled)
    );

    let with_sliding_corner = |t: u32| mesh.tets[t as usize].iter().any(|&v| slides(v));
    assert!(!sliding.sliding_elements.is_empty() && !sliding.implant_elements.is_empty());
    assert!(
        sliding
            .sliding_elements
            .iter()
            .all(|&t| with_sliding_corner(t))
    );
    assert!(
        !sliding
            .implant_elements
            .iter()
            .any(|&t| with_sliding_corner(t))
    );
    let mut elements = [sliding.implant_elements, sliding.sliding_elements].concat();
    elements.sort_unstable();
    let mut held_elements = held.implant_elements.clone();
    held_elements.sort_unstable();
    assert_eq!(elements, held_elements);
    assert!(held.skin_vertices.is_empty() && held.sliding_elements.is_empty());
}

/// The pocket ends at the planned fold. With the fold 10 mm below the implant's centre
/// (its radius is 25 mm) and a 6 mm taper, no vertex under the fold is pushed; a row
/// `h` over it is pushed by `3t² - 2t³` of its push without the fold (`t = h / w`,
/// computed here, `w` the wider of 6 mm and the thickness there, its push's length
/// without the fold), and a row from `w` up as without the fold. Each along the same
/// normal: displacements agree to 1e-12 mm once each template's volume scale is
/// divided out. Unscaled over this flat bed, the cut template inserts less than the
/// covered volume (by more than the 5% `simulate` warns at).
#[test]
fn the_push_ends_smoothly_at_the_planned_fold() {
    let (mesh, ..) = slab();
    let on_wall = vec![false; mesh.positions.len()];
    let fold = FoldPlane {
        point: DVec3::new(0.0, -10.0, 0.0),
        up: DVec3::Y,
        taper_mm: SQUARE_MM,
    };
    let height = |v: u32| mesh.positions[v as usize].y + 10.0;
    let unbounded = slab_template(None, &on_wall);
    let bounded = slab_template_over(None, &on_wall, fold);
    let unscaled = |t: &ImplantTemplate| -> Vec<(u32, DVec3)> {
        (pushed_by_vertex(t).into_iter())
            .map(|(v, d)| (v, d / t.scale))
            .collect()
    };
    let (all, over) = (unscaled(&unbounded), unscaled(&bounded));
    // Over a flat bed the template is not scaled up: what the fold cuts off is missing
    // from what it inserts (the shortfall `simulate` warns of past 5% of the implant).
    println!(
        "over the fold: scale {}, inserts {:.4} of {:.4} ml covered",
        bounded.scale, bounded.template_volume_ml, bounded.covered_volume_ml
    );
    assert!(
        bounded.scale == 1.0 && bounded.template_volume_ml < 0.95 * bounded.covered_volume_ml,
        "scale {}, {} of {} ml",
        bounded.scale,
        bounded.template_volume_ml,
        bounded.covered_volume_ml
    );
    assert!(all.iter().any(|&(v, _)| height(v) < 0.0));
    let (mut widened, mut whole) = (0, 0);
    let expected: Vec<(u32, DVec3)> = (all.into_iter())
        .filter(|&(v, _)| height(v) > 0.0)
        .map(|(v, d)| {
            let width_mm = SQUARE_MM.max(d.length());
            let share = if height(v) < width_mm {
                widened += usize::from(width_mm > SQUARE_MM);
                let t = height(v) / width_mm;
                3.0 * t * t - 2.0 * t * t * t
            } else {
                whole += 1;
                1.0
            };
            (v, d * share)
        })
        .collect();
    // some rows' taper widened by a thickness past 6 mm, some rows pushed whole
    assert!(widened > 0 && whole > 0, "{widened} widened, {whole} whole");
    assert_eq!(over.len(), expected.len());
    for ((v, d), (w, e)) in over.iter().zip(&expected) {
        assert_eq!(v, w);
        assert!(d.distance(*e) < 1e-12, "{v}: {d} vs {e}");
    }
}

/// The share over the fold is taken at each vertex's foot: with the slab's layers laid
/// off along a normal leaning 30 degrees down, the vertices over one bed point get the
/// same push (to 1e-12 mm), although the top one (9 mm out, 4.5 mm lower than its foot)
/// lies under the fold where its foot, 1 mm over it, does not. Taken at the vertex, the
/// top one would get nothing.
#[test]
fn the_share_over_the_fold_is_the_same_along_a_bed_normal() {
    let normal = DVec3::new(0.0, -0.5, 0.75f64.sqrt());
    let (mesh, candidates, feet) = slab_along(normal);
    let fold = FoldPlane {
        point: DVec3::new(0.0, -7.0, 0.0),
        up: DVec3::Y,
        taper_mm: SQUARE_MM,
    };
    let shape = ImplantShape::from(implant::RoundImplant::new(50.0, 8.0).unwrap());
    let on_wall = vec![false; mesh.positions.len()];
    let template = build_template(
        &mesh,
        &candidates,
        &feet,
        &Anchor::flat(),
        &SmoothedThickness::new(shape, 0.0),
        &TemplateRules {
            hold_bed: true,
            layer_mm: 10.0,
            on_wall: &on_wall,
            slides: None,
            fold,
        },
    )
    .unwrap();
    let push = |at: DVec3| {
        let v = (mesh.positions.iter()).position(|p| p.distance(at) < 1e-9);
        let v = v.expect("a slab vertex") as u32;
        (template.pushed_vertices())
            .find(|&&(w, _)| w == v)
            .map(|&(_, d)| d)
    };
    let foot = DVec3::new(0.0, -6.0, 0.0);
    let (middle, top) = (foot + normal * LAYERS_MM[1], foot + normal * LAYERS_MM[2]);
    assert!(fold.height_mm(top) < 0.0 && fold.height_mm(foot) > 0.0);
    let (middle_push, top_push) = (push(middle).unwrap(), push(top).unwrap());
    assert!(middle_push.length() > 0.0);
    assert!(
        middle_push.distance(top_push) < 1e-12,
        "{middle_push} {top_push}"
    );
}
