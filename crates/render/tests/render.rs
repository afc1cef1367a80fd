//! Pictures checked against answers worked out independently of the renderer: areas
//! of discs, projections of known points through known transforms, colours mixed by
//! the sRGB formulas, depth order by construction.

use glam::{DMat3, DQuat, DVec2, DVec3};
use mesh::{DVec2 as MeshVec2, MeshError, TriMesh, UvLayer};
use render::{
    Camera, Colouring, Image, Marker, MeshLayer, Polyline, RenderError, RenderOptions, Scene,
    Shading, StandardView, Texture, Visibility, render,
};

const RED: [u8; 3] = [220, 30, 30];
const BLUE: [u8; 3] = [30, 60, 220];
const TRANSPARENT: [u8; 4] = [0, 0, 0, 0];

/// sRGB level (0-255) to linear light, the IEC 61966-2-1 formula.
fn to_linear(level: u8) -> f64 {
    let c = f64::from(level) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear light to an sRGB level.
fn to_srgb(linear: f64) -> f64 {
    let c = if linear <= 0.0031308 {
        12.92 * linear
    } else {
        1.055 * linear.powf(1.0 / 2.4) - 0.055
    };
    255.0 * c
}

fn unlit(background: [u8; 4]) -> RenderOptions {
    RenderOptions {
        shading: Shading::Unlit,
        background,
        ..RenderOptions::default()
    }
}

/// A camera looking from the front (+z) of the file frame at `target`, one pixel per
/// millimetre in an image `size_px` high.
fn front_camera(target: DVec3, size_px: u32) -> Camera {
    Camera::looking_from(
        StandardView::Front,
        DMat3::IDENTITY,
        target,
        f64::from(size_px),
    )
    .unwrap()
}

/// A rectangle `[x0, x1] × [y0, y1]` at height `z`, facing +z.
fn quad(x0: f64, x1: f64, y0: f64, y1: f64, z: f64) -> TriMesh {
    TriMesh::new(
        vec![
            DVec3::new(x0, y0, z),
            DVec3::new(x1, y0, z),
            DVec3::new(x1, y1, z),
            DVec3::new(x0, y1, z),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    )
}

/// `scene` unlit on white from the front, one pixel per mm, 100x100 pixels centred on
/// the origin.
fn front_picture(scene: &Scene) -> Image {
    render(
        scene,
        &front_camera(DVec3::ZERO, 100),
        100,
        100,
        &unlit([255; 4]),
    )
    .unwrap()
    .image
}

fn rgb(image: &Image, x: u32, y: u32) -> [u8; 3] {
    let [r, g, b, _] = image.pixel(x, y).unwrap();
    [r, g, b]
}

#[test]
fn an_orthographic_sphere_covers_pi_r_squared_pixels() {
    let radius_mm = 50.0;
    let sphere = mesh::shapes::icosphere(radius_mm, 5);
    // 2 pixels per mm: the disc's radius is 100 pixels.
    let (size, pixels_per_mm) = (300u32, 2.0);
    let radius_px = radius_mm * pixels_per_mm;
    let camera = Camera::looking_from(
        StandardView::Front,
        DMat3::IDENTITY,
        DVec3::ZERO,
        f64::from(size) / pixels_per_mm,
    )
    .unwrap();
    let scene = Scene {
        layers: vec![MeshLayer::new(&sphere, Colouring::Uniform(RED))],
        ..Scene::default()
    };
    let image = render(&scene, &camera, size, size, &unlit(TRANSPARENT))
        .unwrap()
        .image;
    let alphas: Vec<u8> = image.rgba().chunks(4).map(|p| p[3]).collect();
    let covered = alphas.iter().filter(|&&a| a >= 128).count() as f64;
    let boundary = alphas.iter().filter(|&&a| a > 0 && a < 255).count() as f64;
    // A pixel on the rim is counted (or not) by whether at least half its samples are
    // inside: each can be off by at most one, and the errors around the rim mostly
    // cancel, so half the rim pixels bound the error. The polyhedron's outline lies
    // inside the sphere's by at most its edge length e squared over 2r in radius, a
    // band of 2πr · e²/(2r) = π e² in area (pixels).
    let edge_px = (0..sphere.triangle_count())
        .flat_map(|t| {
            let [a, b, c] = sphere.triangle_positions(t);
            [a.distance(b), b.distance(c), c.distance(a)]
        })
        .fold(0.0, f64::max)
        * pixels_per_mm;
    let outline_deficit = std::f64::consts::PI * edge_px * edge_px;
    let expected = std::f64::consts::PI * radius_px * radius_px - 0.5 * outline_deficit;
    let tolerance = 0.5 * boundary + 0.5 * outline_deficit;
    assert!(boundary > 0.0 && boundary < 4.0 * 2.0 * std::f64::consts::PI * radius_px);
    assert!(
        (covered - expected).abs() <= tolerance,
        "covered {covered} pixels, π r² = {expected}, tolerance {tolerance}"
    );
    // The disc is centred on the image.
    let (sum, count) = alphas.iter().enumerate().filter(|&(_, &a)| a >= 128).fold(
        (DVec2::ZERO, 0.0),
        |(sum, count), (i, _)| {
            let centre = DVec2::new((i as u32 % size) as f64, (i as u32 / size) as f64) + 0.5;
            (sum + centre, count + 1.0)
        },
    );
    assert!((sum / count).distance(DVec2::splat(f64::from(size) / 2.0)) < 0.5);
}

#[test]
fn the_nearer_of_two_overlapping_quads_shows_whatever_the_drawing_order() {
    // Red at z = 0 from x = -40 to 10, blue at z = 10 (nearer the viewer) from -10 to 40.
    let red = quad(-40.0, 10.0, -20.0, 20.0, 0.0);
    let blue = quad(-10.0, 40.0, -20.0, 20.0, 10.0);
    let camera = front_camera(DVec3::ZERO, 100);
    for perspective in [false, true] {
        let camera = if perspective {
            camera.with_perspective(20f64.to_radians()).unwrap()
        } else {
            camera
        };
        for order in [[&red, &blue], [&blue, &red]] {
            let colour = |mesh: &TriMesh| if *mesh == red { RED } else { BLUE };
            let scene = Scene {
                layers: order
                    .iter()
                    .map(|&mesh| MeshLayer::new(mesh, Colouring::Uniform(colour(mesh))))
                    .collect(),
                ..Scene::default()
            };
            let image = render(&scene, &camera, 100, 100, &unlit([255; 4]))
                .unwrap()
                .image;
            // Columns at x = -30, 0 (the overlap) and 30 mm; row y = 0.
            assert_eq!(rgb(&image, 20, 50), RED, "perspective {perspective}");
            assert_eq!(rgb(&image, 50, 50), BLUE, "perspective {perspective}");
            assert_eq!(rgb(&image, 80, 50), BLUE, "perspective {perspective}");
            assert_eq!(rgb(&image, 50, 5), [255; 3], "background above");
        }
    }
}

#[test]
fn a_marker_lands_on_its_projected_pixel_through_a_known_transform() {
    // The body is turned about an oblique axis and shifted: the marker sits at known body
    // coordinates relative to the target.
    let body = DMat3::from_quat(DQuat::from_axis_angle(
        DVec3::new(1.0, 2.0, -0.5).normalize(),
        0.8,
    ));
    let target = DVec3::new(12.0, 1250.0, -40.0);
    let local = DVec3::new(30.0, -20.0, 15.0); // left, up, anterior (mm)
    let point = target + body * local;
    let backdrop_local = quad(-200.0, 200.0, -200.0, 200.0, -100.0);
    let mut backdrop = backdrop_local.clone();
    backdrop.map_positions(|p| target + body * p);
    let marker_colour = [250, 200, 0];
    let scene = Scene {
        layers: vec![MeshLayer::new(&backdrop, Colouring::Uniform(BLUE))],
        markers: vec![Marker {
            position: point,
            colour: marker_colour,
            label: "M".to_owned(),
        }],
        ..Scene::default()
    };
    let (width, height, view_height_mm) = (400u32, 300u32, 150.0);
    let scale = f64::from(height) / view_height_mm; // pixels per mm
    let centre = DVec2::new(f64::from(width), f64::from(height)) / 2.0;
    // Front: the patient's left is to the right, up is up (pixel rows grow downwards).
    // Left side: anterior is to the left. Perspective front, eye D mm in front of the
    // target: the marker 15 mm nearer than the target is magnified by D / (D - 15).
    let front = Camera::looking_from(StandardView::Front, body, target, view_height_mm).unwrap();
    let side = Camera::looking_from(StandardView::Left, body, target, view_height_mm).unwrap();
    let fov = 15f64.to_radians();
    let eye_distance = 0.5 * view_height_mm / (0.5 * fov).tan();
    let magnification = eye_distance / (eye_distance - local.z);
    let cases = [
        (front, centre + scale * DVec2::new(local.x, -local.y)),
        (side, centre + scale * DVec2::new(-local.z, -local.y)),
        (
            front.with_perspective(fov).unwrap(),
            centre + scale * magnification * DVec2::new(local.x, -local.y),
        ),
    ];
    for (camera, expected) in cases {
        let rendering = render(&scene, &camera, width, height, &RenderOptions::default()).unwrap();
        let placement = &rendering.markers[0];
        assert_eq!(placement.label, "M");
        assert_eq!(placement.visibility, Visibility::Visible);
        assert!(
            placement.pixel.distance(expected) < 1e-6,
            "{} vs {expected}",
            placement.pixel
        );
        let pixel = placement.pixel.floor();
        assert_eq!(
            rgb(&rendering.image, pixel.x as u32, pixel.y as u32),
            marker_colour
        );
    }
}

#[test]
fn markers_behind_the_surface_are_hidden_and_drawn_as_rings() {
    let sphere = mesh::shapes::icosphere(50.0, 4);
    let camera = front_camera(DVec3::ZERO, 200);
    let marker = |position: DVec3, label: &str| Marker {
        position,
        colour: [0, 0, 0],
        label: label.to_owned(),
    };
    // The poles facing and facing away from the viewer; points 5° in front of and
    // behind the outline, where the surface is seen almost edge-on (on the sphere: the
    // polyhedron's faces lie within 0.05 mm of it); a point outside the picture.
    let (sin_5, cos_5) = 5f64.to_radians().sin_cos();
    let scene = Scene {
        layers: vec![MeshLayer::new(&sphere, Colouring::Uniform(RED))],
        markers: vec![
            marker(DVec3::new(0.0, 0.0, 50.0), "front"),
            marker(DVec3::new(0.0, 0.0, -50.0), "back"),
            marker(
                DVec3::new(50.0 * cos_5, 0.0, 50.0 * sin_5),
                "outline, front",
            ),
            marker(
                DVec3::new(50.0 * cos_5, 0.0, -50.0 * sin_5),
                "outline, back",
            ),
            marker(DVec3::new(500.0, 0.0, 0.0), "outside"),
        ],
        ..Scene::default()
    };
    let rendering = render(&scene, &camera, 200, 200, &unlit([255; 4])).unwrap();
    let visibility: Vec<Visibility> = rendering.markers.iter().map(|m| m.visibility).collect();
    assert_eq!(
        visibility,
        [
            Visibility::Visible,
            Visibility::Hidden,
            Visibility::Visible,
            Visibility::Hidden,
            Visibility::OutsideImage
        ]
    );
    // Both poles project onto the centre: the visible disc covers the hidden ring there.
    assert_eq!(rgb(&rendering.image, 100, 100), [0, 0, 0]);
    // Alone, a hidden marker leaves its centre showing the surface.
    let hidden_only = Scene {
        markers: vec![marker(DVec3::new(0.0, 0.0, -50.0), "back")],
        ..scene.clone()
    };
    let rendering = render(&hidden_only, &camera, 200, 200, &unlit([255; 4])).unwrap();
    assert_eq!(rendering.markers[0].visibility, Visibility::Hidden);
    assert_eq!(rgb(&rendering.image, 100, 100), RED);
    let ring = &rendering.image;
    let ring_pixels = (90..110)
        .flat_map(|x| (90..110).map(move |y| (x, y)))
        .filter(|&(x, y)| rgb(ring, x, y) != RED)
        .count();
    assert!(ring_pixels > 10, "the ring is drawn");
}

#[test]
fn colours_interpolate_linearly_across_a_triangle() {
    let corners = [
        DVec3::new(-40.0, -30.0, 0.0),
        DVec3::new(40.0, -30.0, 0.0),
        DVec3::new(0.0, 40.0, 0.0),
    ];
    let mut triangle = TriMesh::new(corners.to_vec(), vec![[0, 1, 2]]);
    let colours = [[255, 0, 0], [0, 255, 0], [0, 0, 255]];
    triangle.vertex_colors = Some(colours.to_vec());
    let scene = Scene {
        layers: vec![MeshLayer::new(&triangle, Colouring::MeshColours)],
        ..Scene::default()
    };
    let image = front_picture(&scene);
    for (column, row) in [(50u32, 50u32), (30, 70), (70, 75), (50, 20), (45, 60)] {
        // The pixel's centre in mm (one pixel per mm, y up) and its barycentric weights.
        let p = DVec2::new(
            f64::from(column) + 0.5 - 50.0,
            50.0 - (f64::from(row) + 0.5),
        );
        let [a, b, c] = corners.map(|v| v.truncate());
        let area = (b - a).perp_dot(c - a);
        let weights = [
            (b - p).perp_dot(c - p) / area,
            (c - p).perp_dot(a - p) / area,
            (a - p).perp_dot(b - p) / area,
        ];
        assert!(weights.iter().all(|&w| w > 0.02), "inside the triangle");
        let got = rgb(&image, column, row);
        for k in 0..3 {
            let linear: f64 = (0..3).map(|v| weights[v] * to_linear(colours[v][k])).sum();
            let expected = to_srgb(linear);
            // One level: the renderer encodes through a table in steps under one level.
            assert!(
                (f64::from(got[k]) - expected).abs() <= 1.0,
                "pixel ({column}, {row}) channel {k}: {} vs {expected:.2}",
                got[k]
            );
        }
    }
}

#[test]
fn a_translucent_layer_mixes_with_what_is_behind_it_in_linear_light() {
    let back = quad(-40.0, 40.0, -40.0, 40.0, 0.0);
    let front = quad(-20.0, 20.0, -20.0, 20.0, 10.0);
    let opacity = 0.4;
    let scene = Scene {
        layers: vec![
            MeshLayer::new(&front, Colouring::Uniform(BLUE)).with_opacity(opacity),
            MeshLayer::new(&back, Colouring::Uniform(RED)),
        ],
        ..Scene::default()
    };
    let image = front_picture(&scene);
    let got = rgb(&image, 50, 50);
    for k in 0..3 {
        let mixed = (1.0 - opacity) * to_linear(RED[k]) + opacity * to_linear(BLUE[k]);
        assert!((f64::from(got[k]) - to_srgb(mixed)).abs() <= 1.0, "{got:?}");
    }
    assert_eq!(rgb(&image, 15, 50), RED, "outside the translucent quad");

    // A second scan of the same surface lies on it within its noise, in front or behind:
    // it tints the whole surface (no specks), until it lies clearly behind.
    for (offset_mm, tinted) in [(0.3, true), (0.0, true), (-0.3, true), (-3.0, false)] {
        let copy = quad(-40.0, 40.0, -40.0, 40.0, offset_mm);
        let scene = Scene {
            layers: vec![
                MeshLayer::new(&back, Colouring::Uniform(RED)),
                MeshLayer::new(&copy, Colouring::Uniform(BLUE)).with_opacity(opacity),
            ],
            ..Scene::default()
        };
        let shown = rgb(&front_picture(&scene), 50, 50);
        assert_eq!(shown == got, tinted, "offset {offset_mm} mm: {shown:?}");
    }
}

#[test]
fn a_texture_is_painted_through_the_texture_coordinates() {
    let mut square = quad(-40.0, 40.0, -40.0, 40.0, 0.0);
    square.uv = Some(UvLayer {
        coords: vec![
            MeshVec2::new(0.0, 0.0),
            MeshVec2::new(1.0, 0.0),
            MeshVec2::new(1.0, 1.0),
            MeshVec2::new(0.0, 1.0),
        ],
        triangles: square.triangles.clone(),
    });
    // A 4x4 texture of four 2x2 blocks, rows from the top (v = 1 is the top row).
    let blocks = [[200, 0, 0], [0, 200, 0], [0, 0, 200], [200, 200, 0]];
    let texels = (0..16).map(|i| blocks[(i / 8) * 2 + (i % 4) / 2]).collect();
    let texture = Texture::new(4, 4, texels).unwrap();
    let scene = Scene {
        layers: vec![MeshLayer::new(&square, Colouring::Texture(&texture))],
        ..Scene::default()
    };
    let image = front_picture(&scene);
    // Each block covers a quarter of the square; their centres are ±20 mm from the
    // middle, where bilinear sampling mixes texels of one block only.
    assert_eq!(rgb(&image, 30, 30), blocks[0], "top left");
    assert_eq!(rgb(&image, 70, 30), blocks[1], "top right");
    assert_eq!(rgb(&image, 30, 70), blocks[2], "bottom left");
    assert_eq!(rgb(&image, 70, 70), blocks[3], "bottom right");
}

#[test]
fn the_inside_of_an_open_surface_is_drawn_tinted() {
    let facing = quad(-40.0, 40.0, -40.0, 40.0, 0.0);
    let mut away = facing.clone();
    for triangle in &mut away.triangles {
        triangle.swap(1, 2);
    }
    let colour_of = |mesh: &TriMesh| {
        let scene = Scene {
            layers: vec![MeshLayer::new(mesh, Colouring::Uniform(RED))],
            ..Scene::default()
        };
        let image = front_picture(&scene);
        rgb(&image, 50, 50)
    };
    assert_eq!(colour_of(&facing), RED);
    let inside = colour_of(&away);
    assert_ne!(inside, RED);
    assert_ne!(inside, [255; 3], "not culled");
}

#[test]
fn curves_show_on_the_visible_side_of_a_surface_only() {
    let sphere = mesh::shapes::icosphere(50.0, 5);
    let circle = |z_sign: f64| -> Vec<DVec3> {
        // A circle 30° from the pole facing (or facing away from) the viewer.
        (0..90)
            .map(|i| {
                let angle = i as f64 * std::f64::consts::TAU / 90.0;
                let (s, c) = 30f64.to_radians().sin_cos();
                50.0 * DVec3::new(s * angle.cos(), s * angle.sin(), z_sign * c)
            })
            .collect()
    };
    let curve_colour = [20, 200, 20];
    let polyline = |points| Polyline {
        points,
        colour: curve_colour,
        closed: true,
        width_px: 3.0,
    };
    let camera = front_camera(DVec3::ZERO, 200);
    for (z_sign, shown) in [(1.0, true), (-1.0, false)] {
        let scene = Scene {
            layers: vec![MeshLayer::new(&sphere, Colouring::Uniform(RED))],
            polylines: vec![polyline(circle(z_sign))],
            ..Scene::default()
        };
        let image = render(&scene, &camera, 200, 200, &unlit([255; 4]))
            .unwrap()
            .image;
        // Sample the curve's pixels: 25 mm from the centre (50 sin 30°).
        let on_curve = (0..36)
            .filter(|&i| {
                let angle = i as f64 * std::f64::consts::TAU / 36.0;
                let pixel = DVec2::new(100.0 + 25.0 * angle.cos(), 100.0 - 25.0 * angle.sin());
                rgb(&image, pixel.x as u32, pixel.y as u32) == curve_colour
            })
            .count();
        if shown {
            assert!(on_curve >= 30, "{on_curve} of 36 points show the curve");
        } else {
            assert_eq!(on_curve, 0, "the curve behind the sphere shows");
        }
    }
}

#[test]
fn bad_input_gives_errors_naming_the_problem() {
    let camera = front_camera(DVec3::ZERO, 100);
    let options = RenderOptions::default();
    let good = quad(-10.0, 10.0, -10.0, 10.0, 0.0);
    let layer = |mesh| Scene {
        layers: vec![MeshLayer::new(mesh, Colouring::Uniform(RED))],
        ..Scene::default()
    };

    let empty = TriMesh::default();
    assert!(matches!(
        render(&layer(&empty), &camera, 10, 10, &options),
        Err(RenderError::Mesh {
            layer: 0,
            source: MeshError::Empty
        })
    ));
    let mut nan = good.clone();
    nan.positions[2].x = f64::NAN;
    assert!(matches!(
        render(&layer(&nan), &camera, 10, 10, &options),
        Err(RenderError::Mesh {
            layer: 0,
            source: MeshError::NonFiniteVertex { vertex: 2, .. }
        })
    ));
    for (width, height) in [(0, 10), (10, 0)] {
        assert!(matches!(
            render(&layer(&good), &camera, width, height, &options),
            Err(RenderError::EmptyImage { .. })
        ));
    }
    let huge = render(&layer(&good), &camera, 100_000, 100_000, &options);
    assert!(matches!(huge, Err(RenderError::ImageTooLarge { .. })));
    let no_supersampling = RenderOptions {
        supersampling: 0,
        ..RenderOptions::default()
    };
    assert!(matches!(
        render(&layer(&good), &camera, 10, 10, &no_supersampling),
        Err(RenderError::Supersampling { found: 0, .. })
    ));

    let mut scene = layer(&good);
    scene.markers.push(Marker {
        position: DVec3::new(0.0, f64::NAN, 0.0),
        colour: RED,
        label: "Pj".to_owned(),
    });
    let error = render(&scene, &camera, 10, 10, &options).unwrap_err();
    assert!(error.to_string().contains("Pj"), "{error}");

    let mut scene = layer(&good);
    scene.polylines.push(Polyline {
        points: vec![DVec3::ZERO, DVec3::INFINITY],
        colour: RED,
        closed: false,
        width_px: 2.0,
    });
    assert!(matches!(
        render(&scene, &camera, 10, 10, &options),
        Err(RenderError::NonFinitePolyline {
            polyline: 0,
            point: 1,
            ..
        })
    ));

    let short_colours = [RED; 3];
    let scene = Scene {
        layers: vec![MeshLayer::new(&good, Colouring::PerVertex(&short_colours))],
        ..Scene::default()
    };
    assert!(matches!(
        render(&scene, &camera, 10, 10, &options),
        Err(RenderError::ColourCount {
            found: 3,
            expected: 4,
            ..
        })
    ));
    let scene = Scene {
        layers: vec![MeshLayer::new(&good, Colouring::MeshColours)],
        ..Scene::default()
    };
    assert!(matches!(
        render(&scene, &camera, 10, 10, &options),
        Err(RenderError::NoVertexColours { layer: 0 })
    ));
    let texture = Texture::new(1, 1, vec![RED]).unwrap();
    let scene = Scene {
        layers: vec![MeshLayer::new(&good, Colouring::Texture(&texture))],
        ..Scene::default()
    };
    assert!(matches!(
        render(&scene, &camera, 10, 10, &options),
        Err(RenderError::NoTextureCoordinates { layer: 0 })
    ));
    assert!(Texture::new(2, 2, vec![RED]).is_err());
    let scene = Scene {
        layers: vec![MeshLayer::new(&good, Colouring::Uniform(RED)).with_opacity(1.5)],
        ..Scene::default()
    };
    assert!(matches!(
        render(&scene, &camera, 10, 10, &options),
        Err(RenderError::Opacity { layer: 0, .. })
    ));
    let mut bad_camera = camera;
    bad_camera.target.x = f64::NAN;
    assert!(matches!(
        render(&layer(&good), &bad_camera, 10, 10, &options),
        Err(RenderError::Camera(_))
    ));
}
