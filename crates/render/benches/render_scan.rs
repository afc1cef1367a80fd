//! One standard view of a torso scan at report size (issue 7: a 92,000-vertex scan at
//! about 800x1000 pixels with 2x2 supersampling well under a second on the 2-core
//! machine): the phantom scan (145,245 vertices, more than the shared scans' 92,000)
//! from the front and the left oblique, skin tone, its twelve landmarks as markers;
//! then the PNG encoding of the picture.

use anatomy::{AnatomicalFrame, Up};
use criterion::{Criterion, criterion_group, criterion_main};
use phantom::PhantomParams;
use render::{
    Camera, Colouring, Marker, MeshLayer, RenderOptions, SKIN_TONE, Scene, StandardView,
    encode_png, render,
};
use std::hint::black_box;

const WIDTH: u32 = 800;
const HEIGHT: u32 = 1000;

fn bench_render(c: &mut Criterion) {
    let phantom = phantom::generate(&PhantomParams::default());
    let frame = AnatomicalFrame::from_landmarks(&phantom.landmarks, Up::FILE_VERTICAL)
        .expect("the phantom's frame");
    let scene = Scene {
        layers: vec![MeshLayer::new(&phantom.scan, Colouring::Uniform(SKIN_TONE))],
        markers: phantom
            .landmarks
            .iter()
            .map(|(name, position)| Marker {
                position,
                colour: [30, 90, 200],
                label: name.to_owned(),
            })
            .collect(),
        polylines: Vec::new(),
    };
    let options = RenderOptions::default();
    let mut group = c.benchmark_group("render");
    group.sample_size(10);
    for view in [StandardView::Front, StandardView::LeftOblique] {
        let camera = Camera::framing(
            view,
            frame.axes,
            &phantom.scan.positions,
            f64::from(WIDTH) / f64::from(HEIGHT),
        )
        .expect("a camera");
        group.bench_function(
            format!(
                "{} view, {} vertices, {WIDTH}x{HEIGHT}, 2x2 samples",
                view.id(),
                phantom.scan.vertex_count()
            ),
            |b| {
                b.iter(|| {
                    render(black_box(&scene), &camera, WIDTH, HEIGHT, &options).expect("a picture")
                })
            },
        );
    }
    let camera = Camera::framing(
        StandardView::Front,
        frame.axes,
        &phantom.scan.positions,
        f64::from(WIDTH) / f64::from(HEIGHT),
    )
    .expect("a camera");
    let picture = render(&scene, &camera, WIDTH, HEIGHT, &options).expect("a picture");
    group.bench_function(format!("encode_png {WIDTH}x{HEIGHT}"), |b| {
        b.iter(|| encode_png(black_box(&picture.image)).expect("a PNG"))
    });
    group.finish();
}

criterion_group!(benches, bench_render);
criterion_main!(benches);
