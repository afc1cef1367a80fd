//! Drawing the scan in the viewport with wgpu, through an `egui_wgpu` paint callback.
//!
//! `prepare` draws the lit meshes into the viewport's own colour and depth textures
//! (multisampled when the adapter allows), so the 3D scene has a real depth buffer
//! whatever egui's render pass has; `paint` then copies the resolved colour into egui's
//! pass with a full-viewport triangle. The scene is drawn again only when it changed
//! (meshes, camera or size): a window frame for the panels alone (a hover, a solver
//! status) only copies it, which matters with a software renderer, where drawing the
//! 290,000 triangles of a scan costs tens of milliseconds. Up to [`MAX_LAYERS`] meshes are drawn in order:
//! opaque ones, then a translucent one blended over them (the simulated scan over the
//! pre-operative one). A simulated scan shares its triangles with the scan it moves, so
//! its updates rewrite the vertex buffer only. Shading: per-vertex normals, a light slightly
//! above and to the left of the eye, Lambert diffuse plus a weak Blinn-Phong highlight;
//! back faces (the inside of an open scan) are lit from their own side and tinted (not
//! drawn at all with a software renderer, see [`install`]). With a software renderer a
//! running solve's frames trade detail for rate, as a level of detail does: they are
//! drawn on an [`InteractionMesh`] (an eighth of the triangles) into a picture of half
//! the viewport's pixels ([`INTERACTION_PIXEL_SCALE`]), which the copy into egui's pass
//! scales up; the settled frame is drawn in full.
//! Colours are the scan's vertex colours when it has them, else its photograph sampled at
//! the vertices (a per-pixel GPU texture is not drawn yet), else a neutral skin tone.

use crate::camera::Camera;
use bytemuck::{Pod, Zeroable};
use eframe::egui;
use eframe::egui_wgpu::{self, wgpu};
use glam::{DMat4, DVec2, DVec3};
use mesh::TriMesh;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use wgpu::util::DeviceExt;

/// Colour of a scan without vertex colours (display RGB, 0..1).
const SKIN: [f32; 3] = [0.86, 0.72, 0.64];
/// Background of the viewport (display RGB, 0..1).
const BACKGROUND: [f64; 3] = [0.16, 0.17, 0.19];
/// Offscreen colour format; shading happens in display (gamma) space.
const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Wanted multisampling of the scene (1 if the adapter cannot, or renders on the CPU).
const MSAA_SAMPLES: u32 = 4;
/// Most meshes drawn at once.
pub const MAX_LAYERS: usize = 2;
/// Linear scale of the scene's picture against the viewport's pixels while a running
/// solve's frames are drawn with a software renderer: half the pixels (its effect on the
/// live view's rate: docs/user/gui.md).
pub const INTERACTION_PIXEL_SCALE: f64 = std::f64::consts::FRAC_1_SQRT_2;
/// Colour factor and opacity of a translucent layer: a light blue veil.
const TRANSLUCENT_TINT: [f32; 4] = [0.78, 0.88, 1.0, 0.45];

const SHADER: &str = r#"
struct Uniforms {
    view_proj: mat4x4<f32>,
    eye: vec4<f32>,
    light: vec4<f32>,
    tint: vec4<f32>,
};
@group(0) @binding(0) var<uniform> u: Uniforms;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec3<f32>,
};
struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec3<f32>,
};

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = u.view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    out.color = v.color;
    return out;
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    var n = normalize(in.normal);
    var base = in.color;
    if (!front) {
        n = -n;
        base = base * vec3<f32>(0.55, 0.6, 0.75);
    }
    let to_eye = normalize(u.eye.xyz - in.world);
    let to_light = normalize(u.light.xyz);
    let diffuse = max(dot(n, to_light), 0.0);
    let half_way = normalize(to_light + to_eye);
    let specular = pow(max(dot(n, half_way), 0.0), 48.0) * 0.18;
    let lit = (base * (0.22 + 0.78 * diffuse) + vec3<f32>(specular)) * u.tint.rgb;
    return vec4<f32>(min(lit, vec3<f32>(1.0)), u.tint.a);
}
"#;

const BLIT_SHADER: &str = r#"
@group(0) @binding(0) var scene: texture_2d<f32>;
@group(0) @binding(1) var scene_sampler: sampler;

struct BlitOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

@vertex
fn vs_blit(@builtin(vertex_index) index: u32) -> BlitOut {
    // One triangle covering the viewport.
    let xy = vec2<f32>(f32((index << 1u) & 2u), f32(index & 2u));
    var out: BlitOut;
    out.clip = vec4<f32>(xy * 2.0 - 1.0, 0.0, 1.0);
    out.uv = vec2<f32>(xy.x, 1.0 - xy.y);
    return out;
}

@fragment
fn fs_blit_gamma(in: BlitOut) -> @location(0) vec4<f32> {
    return textureSample(scene, scene_sampler, in.uv);
}

@fragment
fn fs_blit_linear(in: BlitOut) -> @location(0) vec4<f32> {
    let c = textureSample(scene, scene_sampler, in.uv);
    return vec4<f32>(pow(c.rgb, vec3<f32>(2.2)), c.a);
}
"#;

/// One vertex of the scene: position relative to the mesh's centre (mm), unit normal
/// and display colour.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct Vertex {
    position: [f32; 3],
    normal: [f32; 3],
    color: [f32; 3],
}

/// A scan turned into GPU-ready buffers, uploaded once per scan.
pub struct SceneMesh {
    /// Tells meshes apart so each is uploaded once.
    generation: u64,
    /// Tells triangle lists apart: a moved copy of a scan keeps its scan's, and only its
    /// vertices are uploaded again.
    topology: u64,
    /// Positions are stored relative to this point (mm, file frame), so f32 keeps
    /// sub-micrometre precision however far the scan is from its file's origin.
    origin: DVec3,
    vertices: Vec<Vertex>,
    indices: Arc<Vec<u32>>,
    /// The scan vertex each vertex shows, when they are not the scan's own in order (an
    /// [`InteractionMesh`]'s frames).
    scan_vertices: Option<Arc<Vec<u32>>>,
}

/// A coarser triangulation of a scan on a subset of its vertices, drawn for the live
/// simulation's frames while the solver runs when the window draws on the processor: a
/// software renderer's cost is per triangle, and at the viewport's size an eighth of a
/// 290,000-triangle scan's triangles shows the same shape. Its vertices are scan
/// vertices, moved by their own simulated displacements; once the solver settles, the
/// full scan is drawn again.
pub struct InteractionMesh {
    /// Tells its frames' triangle lists apart from the scan's.
    topology: u64,
    /// The scan vertex of each of its vertices (ascending).
    scan_vertices: Arc<Vec<u32>>,
    /// Its triangles' corners, three per triangle, over its own vertices.
    indices: Arc<Vec<u32>>,
    /// The simplifier's estimate of the largest distance between its surface and the
    /// scan's (mm).
    error_mm: f64,
}

/// Numbers for [`SceneMesh::generation`] and [`SceneMesh::topology`].
static NEXT_ID: AtomicU64 = AtomicU64::new(0);

impl SceneMesh {
    /// Vertex normals, colours (or the skin tone) and positions about the bounding box
    /// centre.
    pub fn new(mesh: &TriMesh) -> SceneMesh {
        let (low, high) = mesh.bounding_box();
        let colors = |i: usize| {
            mesh.vertex_colors
                .as_ref()
                .and_then(|colors| colors.get(i))
                .map_or(SKIN, |c| c.map(|v| f32::from(v) / 255.0))
        };
        SceneMesh {
            generation: NEXT_ID.fetch_add(1, Ordering::Relaxed),
            topology: NEXT_ID.fetch_add(1, Ordering::Relaxed),
            origin: 0.5 * (low + high),
            vertices: Vec::new(),
            indices: Arc::new(mesh.triangles.iter().flatten().copied().collect()),
            scan_vertices: None,
        }
        .with_vertices(mesh, colors)
    }

    /// A scan as [`SceneMesh::new`] draws it, wearing its photograph where it has one
    /// and no vertex colours: the texture sampled at every vertex
    /// ([`plan::texture::vertex_colours`]), so at the scan's own resolution.
    pub fn of_scan(scan: &plan::Scan) -> SceneMesh {
        let baked = scan
            .texture
            .as_ref()
            .filter(|_| scan.mesh.vertex_colors.is_none())
            .and_then(|texture| plan::texture::vertex_colours(&scan.mesh, &texture.image));
        match baked {
            Some(colours) => {
                let mut mesh = scan.mesh.clone();
                mesh.vertex_colors = Some(colours);
                SceneMesh::new(&mesh)
            }
            None => SceneMesh::new(&scan.mesh),
        }
    }

    /// The number of triangles drawn.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// The same scan with its vertices moved to those of `moved` (the scan's triangles
    /// and vertex order; new normals, the same colours and origin).
    pub fn moved(&self, moved: &TriMesh) -> SceneMesh {
        debug_assert_eq!(moved.positions.len(), self.vertices.len());
        SceneMesh {
            generation: NEXT_ID.fetch_add(1, Ordering::Relaxed),
            topology: self.topology,
            origin: self.origin,
            vertices: Vec::new(),
            indices: Arc::clone(&self.indices),
            scan_vertices: self.scan_vertices.clone(),
        }
        .with_vertices(moved, |i| self.vertices[i].color)
    }

    /// The interaction mesh `coarse` of this scan (built from it) with its vertices at
    /// `moved` (its own vertices' positions, mm, in its order; normals from its own
    /// triangles; the scan's colours).
    pub fn coarse_moved(&self, coarse: &InteractionMesh, moved: &TriMesh) -> SceneMesh {
        debug_assert!(self.scan_vertices.is_none(), "a full scan's scene");
        debug_assert_eq!(moved.positions.len(), coarse.scan_vertices.len());
        SceneMesh {
            generation: NEXT_ID.fetch_add(1, Ordering::Relaxed),
            topology: coarse.topology,
            origin: self.origin,
            vertices: Vec::new(),
            indices: Arc::clone(&coarse.indices),
            scan_vertices: Some(Arc::clone(&coarse.scan_vertices)),
        }
        .with_vertices(moved, |i| {
            self.vertices[coarse.scan_vertices[i] as usize].color
        })
    }

    /// The same mesh drawn in other colours (display RGB, one per scan vertex; a colour
    /// map).
    pub fn recoloured(&self, colors: &[[u8; 3]]) -> SceneMesh {
        let scan_vertex = |i: usize| self.scan_vertices.as_ref().map_or(i, |s| s[i] as usize);
        SceneMesh {
            generation: NEXT_ID.fetch_add(1, Ordering::Relaxed),
            topology: self.topology,
            origin: self.origin,
            vertices: (self.vertices.iter().enumerate())
                .map(|(i, vertex)| Vertex {
                    color: colors[scan_vertex(i)].map(|c| f32::from(c) / 255.0),
                    ..*vertex
                })
                .collect(),
            indices: Arc::clone(&self.indices),
            scan_vertices: self.scan_vertices.clone(),
        }
    }

    fn with_vertices(mut self, mesh: &TriMesh, color: impl Fn(usize) -> [f32; 3]) -> SceneMesh {
        let normals = mesh.vertex_normals();
        self.vertices = mesh
            .positions
            .iter()
            .zip(&normals)
            .enumerate()
            .map(|(i, (p, n))| Vertex {
                position: (*p - self.origin).as_vec3().to_array(),
                normal: n.as_vec3().to_array(),
                color: color(i),
            })
            .collect();
        self
    }
}

impl InteractionMesh {
    /// Simplifies the scan drawn as `scene` (a full scan, from [`SceneMesh::new`]) to
    /// `triangle_share` of its triangles by meshoptimizer's quadric edge collapses
    /// (borders kept, vertices kept where they are), or to more triangles where fewer
    /// would take its surface further than `error_mm` from the scan's (the simplifier's
    /// own estimate). Written by meshoptimizer's authors, not by hand:
    /// its simplifier is the field's standard and keeps the original vertices, which is
    /// what lets each frame move them by their own displacements.
    pub fn simplify(scene: &SceneMesh, triangle_share: f64, error_mm: f64) -> InteractionMesh {
        debug_assert!(scene.scan_vertices.is_none(), "a full scan's scene");
        let bytes: &[u8] = bytemuck::cast_slice(&scene.vertices);
        let mut reached_error_mm = 0.0f32;
        let simplified = match meshopt::VertexDataAdapter::new(bytes, size_of::<Vertex>(), 0) {
            Ok(adapter) => meshopt::simplify(
                &scene.indices,
                &adapter,
                (scene.indices.len() as f64 * triangle_share) as usize / 3 * 3,
                error_mm as f32,
                meshopt::SimplifyOptions::LockBorder | meshopt::SimplifyOptions::ErrorAbsolute,
                Some(&mut reached_error_mm),
            ),
            // Cannot happen (the stride is the vertex's size): draw the scan itself.
            Err(_) => scene.indices.to_vec(),
        };
        let mut own = vec![u32::MAX; scene.vertices.len()];
        let mut scan_vertices: Vec<u32> = simplified.clone();
        scan_vertices.sort_unstable();
        scan_vertices.dedup();
        for (k, &v) in scan_vertices.iter().enumerate() {
            own[v as usize] = k as u32;
        }
        let indices = simplified.iter().map(|&v| own[v as usize]).collect();
        InteractionMesh {
            topology: NEXT_ID.fetch_add(1, Ordering::Relaxed),
            scan_vertices: Arc::new(scan_vertices),
            indices: Arc::new(indices),
            error_mm: f64::from(reached_error_mm),
        }
    }

    /// The simplifier's estimate of the largest distance between its surface and the
    /// scan's (mm).
    pub fn error_mm(&self) -> f64 {
        self.error_mm
    }

    /// The scan vertex of each of its vertices.
    pub fn scan_vertices(&self) -> &[u32] {
        &self.scan_vertices
    }

    /// Its triangles (over its own vertices), for a [`TriMesh`] of its frames.
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        (self.indices.chunks_exact(3))
            .map(|t| [t[0], t[1], t[2]])
            .collect()
    }
}

#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
struct Uniforms {
    view_proj: [[f32; 4]; 4],
    eye: [f32; 4],
    light: [f32; 4],
    tint: [f32; 4],
}

/// How a mesh is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LayerStyle {
    Opaque,
    /// Blended over what is drawn before it ([`TRANSLUCENT_TINT`]), hiding nothing.
    Translucent,
}

/// One mesh of the viewport.
#[derive(Clone)]
pub struct Layer {
    pub scene: Arc<SceneMesh>,
    pub style: LayerStyle,
}

/// The GPU objects of the viewport, kept in egui_wgpu's callback resources.
struct ViewportResources {
    opaque_pipeline: wgpu::RenderPipeline,
    translucent_pipeline: wgpu::RenderPipeline,
    blit_pipeline: wgpu::RenderPipeline,
    blit_layout: wgpu::BindGroupLayout,
    sampler: wgpu::Sampler,
    /// One uniform buffer and group per layer.
    uniforms: Vec<(wgpu::Buffer, wgpu::BindGroup)>,
    samples: u32,
    meshes: [Option<GpuMesh>; MAX_LAYERS],
    target: Option<Target>,
    /// What the target holds.
    drawn: Option<DrawnScene>,
}

/// What a scene drawn into the offscreen target was made of: when a frame asks for the
/// same, the target is reused as it is.
#[derive(PartialEq)]
struct DrawnScene {
    size: [u32; 2],
    /// Each layer's mesh generation, style and uniforms (camera, light, tint).
    layers: Vec<(u64, LayerStyle, Uniforms)>,
}

struct GpuMesh {
    generation: u64,
    topology: u64,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    index_count: u32,
}

/// The offscreen textures of one viewport size.
struct Target {
    size: [u32; 2],
    multisampled: Option<wgpu::TextureView>,
    resolved: wgpu::TextureView,
    depth: wgpu::TextureView,
    blit_group: wgpu::BindGroup,
}

/// Creates the pipelines and stores them in the renderer's callback resources; call
/// once with the app's wgpu state. Returns whether the renderer is a software one
/// (drawing on the processor).
pub fn install(render_state: &egui_wgpu::RenderState) -> bool {
    let device = &render_state.device;
    let features = render_state
        .adapter
        .get_texture_format_features(COLOR_FORMAT);
    let depth_features = render_state
        .adapter
        .get_texture_format_features(DEPTH_FORMAT);
    // A software renderer (Mesa's llvmpipe) pays for multisampling with every sample, and
    // for every triangle, even one hidden or facing away: there, one sample and drawing
    // front faces only keep the live view fluid (at 60,000 elements on two cores, culling
    // the back faces raised the view updates from about 8.7 to 9.7 per second). The
    // inside of an open scan, seen through its openings, is then not drawn.
    let software = render_state.adapter.get_info().device_type == wgpu::DeviceType::Cpu;
    let cull_mode = software.then_some(wgpu::Face::Back);
    let samples = if !software
        && features.flags.sample_count_supported(MSAA_SAMPLES)
        && depth_features.flags.sample_count_supported(MSAA_SAMPLES)
    {
        MSAA_SAMPLES
    } else {
        1
    };

    let scene_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("mammaplan scene shader"),
        source: wgpu::ShaderSource::Wgsl(SHADER.into()),
    });
    let (uniform_layout, uniforms) = layer_uniforms(device);
    let scene_layout = pipeline_layout(device, "mammaplan scene layout", &uniform_layout);
    let [opaque_pipeline, translucent_pipeline] = [LayerStyle::Opaque, LayerStyle::Translucent]
        .map(|style| {
            scene_pipeline(
                device,
                &scene_module,
                &scene_layout,
                style,
                cull_mode,
                samples,
            )
        });
    let (blit_pipeline, blit_layout, sampler) = blit_pipeline(device, render_state.target_format);

    render_state
        .renderer
        .write()
        .callback_resources
        .insert(ViewportResources {
            opaque_pipeline,
            translucent_pipeline,
            blit_pipeline,
            blit_layout,
            sampler,
            uniforms,
            samples,
            meshes: [None, None],
            target: None,
            drawn: None,
        });
    software
}

/// The uniforms layout, and a buffer and bind group of it for each layer.
fn layer_uniforms(
    device: &wgpu::Device,
) -> (wgpu::BindGroupLayout, Vec<(wgpu::Buffer, wgpu::BindGroup)>) {
    let uniform_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("mammaplan uniforms layout"),
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        }],
    });
    let uniforms = (0..MAX_LAYERS)
        .map(|_| {
            let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("mammaplan uniforms"),
                contents: bytemuck::bytes_of(&Uniforms::zeroed()),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            });
            let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("mammaplan uniforms"),
                layout: &uniform_layout,
                entries: &[wgpu::BindGroupEntry {
                    binding: 0,
                    resource: buffer.as_entire_binding(),
                }],
            });
            (buffer, group)
        })
        .collect();
    (uniform_layout, uniforms)
}

/// The pipeline that draws a layer of `style` into the offscreen target.
fn scene_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    layout: &wgpu::PipelineLayout,
    style: LayerStyle,
    cull_mode: Option<wgpu::Face>,
    samples: u32,
) -> wgpu::RenderPipeline {
    let translucent = style == LayerStyle::Translucent;
    let attributes = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x3];
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("mammaplan scene"),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_main"),
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: std::mem::size_of::<Vertex>() as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &attributes,
            })],
            compilation_options: wgpu::PipelineCompilationOptions::default(),
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            front_face: wgpu::FrontFace::Ccw,
            cull_mode,
            ..wgpu::PrimitiveState::default()
        },
        // A translucent layer hides nothing behind it, and where it coincides with an
        // opaque one (the simulated scan where nothing moved) it is still drawn.
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(!translucent),
            depth_compare: Some(if translucent {
                wgpu::CompareFunction::LessEqual
            } else {
                wgpu::CompareFunction::Less
            }),
            stencil: wgpu::StencilState::default(),
            // Pulled a little towards the eye, so that where the simulated scan lies within
            // rounding of the pre-operative one (far from the breasts, where the
            // displacement has faded out) it wins the depth test everywhere, not in
            // speckles.
            bias: if translucent {
                wgpu::DepthBiasState {
                    constant: -8,
                    slope_scale: -1.0,
                    clamp: 0.0,
                }
            } else {
                wgpu::DepthBiasState::default()
            },
        }),
        multisample: wgpu::MultisampleState {
            count: samples,
            mask: !0,
            alpha_to_coverage_enabled: false,
        },
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some("fs_main"),
            targets: &[Some(wgpu::ColorTargetState {
                format: COLOR_FORMAT,
                blend: translucent.then_some(wgpu::BlendState::ALPHA_BLENDING),
                write_mask: wgpu::ColorWrites::ALL,
            })],
            compilation_options: wgpu::PipelineCompilationOptions::default(),
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// The pipeline that copies the offscreen target into egui's pass in `target_format`,
/// its bind group layout and its sampler.
fn blit_pipeline(
    device: &wgpu::Device,
    target_format: wgpu::TextureFormat,
) -> (wgpu::RenderPipeline, wgpu::BindGroupLayout, wgpu::Sampler) {
    let blit_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("mammaplan blit shader"),
        source: wgpu::ShaderSource::Wgsl(BLIT_SHADER.into()),
    });
    let blit_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("mammaplan blit layout"),
        entries: &[
            wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    multisampled: false,
                    sample_type: wgpu::TextureSampleType::Float { filterable: true },
                    view_dimension: wgpu::TextureViewDimension::D2,
                },
                count: None,
            },
            wgpu::BindGroupLayoutEntry {
                binding: 1,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                count: None,
            },
        ],
    });
    let blit_pipeline_layout = pipeline_layout(device, "mammaplan blit layout", &blit_layout);
    let blit_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("mammaplan blit"),
        layout: Some(&blit_pipeline_layout),
        vertex: wgpu::VertexState {
            module: &blit_module,
            entry_point: Some("vs_blit"),
            buffers: &[],
            compilation_options: wgpu::PipelineCompilationOptions::default(),
        },
        primitive: wgpu::PrimitiveState::default(),
        // egui's own pass: no depth, one sample (eframe's defaults, kept by `run`).
        depth_stencil: None,
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module: &blit_module,
            entry_point: Some(if target_format.is_srgb() {
                "fs_blit_linear"
            } else {
                "fs_blit_gamma"
            }),
            targets: &[Some(wgpu::ColorTargetState {
                format: target_format,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
            compilation_options: wgpu::PipelineCompilationOptions::default(),
        }),
        multiview_mask: None,
        cache: None,
    });
    let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("mammaplan blit sampler"),
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        ..wgpu::SamplerDescriptor::default()
    });
    (blit_pipeline, blit_layout, sampler)
}

/// A pipeline layout with one bind group.
fn pipeline_layout(
    device: &wgpu::Device,
    label: &str,
    group: &wgpu::BindGroupLayout,
) -> wgpu::PipelineLayout {
    device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(group)],
        immediate_size: 0,
    })
}

/// One frame of the viewport: what `prepare` needs to draw.
pub struct ViewportCallback {
    pub camera: Camera,
    /// Drawn in order (at most [`MAX_LAYERS`]).
    pub layers: Vec<Layer>,
    /// Viewport size in egui points (the paint callback's rectangle).
    pub size_points: DVec2,
    /// Linear scale of the scene's picture against the viewport's pixels (1: every
    /// pixel drawn; below 1 the copy into egui's pass scales it up).
    pub pixel_scale: f64,
}

impl ViewportCallback {
    fn uniforms(&self, layer: &Layer) -> Uniforms {
        let origin = layer.scene.origin;
        let view_proj =
            self.camera.view_projection(self.size_points) * DMat4::from_translation(origin);
        let eye = self.camera.eye() - origin;
        // The key light sits above and to the left of the eye.
        let light = self.camera.backward() + 0.45 * self.camera.up() - 0.35 * self.camera.right();
        Uniforms {
            view_proj: view_proj.as_mat4().to_cols_array_2d(),
            eye: eye.as_vec3().extend(1.0).to_array(),
            light: light.normalize().as_vec3().extend(0.0).to_array(),
            tint: match layer.style {
                LayerStyle::Opaque => [1.0; 4],
                LayerStyle::Translucent => TRANSLUCENT_TINT,
            },
        }
    }
}

impl egui_wgpu::CallbackTrait for ViewportCallback {
    fn prepare(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        screen: &egui_wgpu::ScreenDescriptor,
        encoder: &mut wgpu::CommandEncoder,
        resources: &mut egui_wgpu::CallbackResources,
    ) -> Vec<wgpu::CommandBuffer> {
        let Some(viewport) = resources.get_mut::<ViewportResources>() else {
            return Vec::new();
        };
        let pixels = self.size_points * f64::from(screen.pixels_per_point) * self.pixel_scale;
        let size = [
            (pixels.x.round() as u32).max(1),
            (pixels.y.round() as u32).max(1),
        ];
        let layers = &self.layers[..self.layers.len().min(MAX_LAYERS)];
        let scene = DrawnScene {
            size,
            layers: (layers.iter())
                .map(|layer| (layer.scene.generation, layer.style, self.uniforms(layer)))
                .collect(),
        };
        if viewport.drawn.as_ref() == Some(&scene) {
            return Vec::new();
        }
        for (k, (layer, (_, _, uniforms))) in layers.iter().zip(&scene.layers).enumerate() {
            upload_mesh(&mut viewport.meshes[k], device, queue, &layer.scene);
            queue.write_buffer(&viewport.uniforms[k].0, 0, bytemuck::bytes_of(uniforms));
        }
        viewport.resize(device, size);
        viewport.drawn = Some(scene);
        let Some(target) = &viewport.target else {
            return Vec::new();
        };
        let (view, resolve_target) = match &target.multisampled {
            Some(multisampled) => (multisampled, Some(&target.resolved)),
            None => (&target.resolved, None),
        };
        let [r, g, b] = BACKGROUND;
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("mammaplan scene"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                resolve_target,
                depth_slice: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a: 1.0 }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &target.depth,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            ..wgpu::RenderPassDescriptor::default()
        });
        for (k, layer) in layers.iter().enumerate() {
            let Some(mesh) = &viewport.meshes[k] else {
                continue;
            };
            pass.set_pipeline(match layer.style {
                LayerStyle::Opaque => &viewport.opaque_pipeline,
                LayerStyle::Translucent => &viewport.translucent_pipeline,
            });
            pass.set_bind_group(0, &viewport.uniforms[k].1, &[]);
            pass.set_vertex_buffer(0, mesh.vertices.slice(..));
            pass.set_index_buffer(mesh.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..mesh.index_count, 0, 0..1);
        }
        Vec::new()
    }

    fn paint(
        &self,
        _info: egui::PaintCallbackInfo,
        render_pass: &mut wgpu::RenderPass<'static>,
        resources: &egui_wgpu::CallbackResources,
    ) {
        let Some(viewport) = resources.get::<ViewportResources>() else {
            return;
        };
        let Some(target) = &viewport.target else {
            return;
        };
        render_pass.set_pipeline(&viewport.blit_pipeline);
        render_pass.set_bind_group(0, &target.blit_group, &[]);
        render_pass.draw(0..3, 0..1);
    }
}

/// Puts a scene's buffers into a layer's slot unless they are there: only the vertices
/// when the slot holds the same triangles, everything otherwise.
fn upload_mesh(
    slot: &mut Option<GpuMesh>,
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    scene: &SceneMesh,
) {
    match slot {
        Some(mesh) if mesh.generation == scene.generation => {}
        Some(mesh) if mesh.topology == scene.topology => {
            queue.write_buffer(&mesh.vertices, 0, bytemuck::cast_slice(&scene.vertices));
            mesh.generation = scene.generation;
        }
        _ => {
            *slot = Some(GpuMesh {
                generation: scene.generation,
                topology: scene.topology,
                vertices: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("mammaplan scan vertices"),
                    contents: bytemuck::cast_slice(&scene.vertices),
                    usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                }),
                indices: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("mammaplan scan triangles"),
                    contents: bytemuck::cast_slice(scene.indices.as_slice()),
                    usage: wgpu::BufferUsages::INDEX,
                }),
                index_count: scene.indices.len() as u32,
            });
        }
    }
}

impl ViewportResources {
    /// (Re)creates the offscreen textures for a viewport of `size` pixels.
    fn resize(&mut self, device: &wgpu::Device, size: [u32; 2]) {
        if self.target.as_ref().is_some_and(|t| t.size == size) {
            return;
        }
        let texture = |label, format, samples, usage| {
            device
                .create_texture(&wgpu::TextureDescriptor {
                    label: Some(label),
                    size: wgpu::Extent3d {
                        width: size[0],
                        height: size[1],
                        depth_or_array_layers: 1,
                    },
                    mip_level_count: 1,
                    sample_count: samples,
                    dimension: wgpu::TextureDimension::D2,
                    format,
                    usage,
                    view_formats: &[],
                })
                .create_view(&wgpu::TextureViewDescriptor::default())
        };
        let resolved = texture(
            "mammaplan scene colour",
            COLOR_FORMAT,
            1,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let multisampled = (self.samples > 1).then(|| {
            texture(
                "mammaplan scene colour (multisampled)",
                COLOR_FORMAT,
                self.samples,
                wgpu::TextureUsages::RENDER_ATTACHMENT,
            )
        });
        let depth = texture(
            "mammaplan scene depth",
            DEPTH_FORMAT,
            self.samples,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let blit_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("mammaplan blit"),
            layout: &self.blit_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&resolved),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(&self.sampler),
                },
            ],
        });
        self.target = Some(Target {
            size,
            multisampled,
            resolved,
            depth,
            blit_group,
        });
    }
}

/// The viewport's background as an egui colour (for the area without a GPU).
pub fn background() -> egui::Color32 {
    let [r, g, b] = BACKGROUND.map(|c| (c * 255.0).round() as u8);
    egui::Color32::from_rgb(r, g, b)
}
