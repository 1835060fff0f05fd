//! Every WGSL file parses and validates with naga (no GPU needed), and every uniform struct
//! of the shaders has the size and member offsets its `bytemuck::Pod` mirror in Rust has.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

use harness::render::{DrawUniform, FrameUniform, OCCLUSION_WGSL, SHADER_MODULES, SPLAT_WGSL};

fn shaders() -> Vec<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut out = Vec::new();
    let mut stack = vec![dir];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "wgsl") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

fn module(name: &str, src: &str) -> (naga::Module, naga::valid::ModuleInfo) {
    let m = naga::front::wgsl::parse_str(src)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(src)));
    let info = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&m)
    .unwrap_or_else(|e| panic!("{name}: {e:?}"));
    (m, info)
}

/// The renderer's modules and the viewer's presentation pass.
fn all_modules() -> Vec<(&'static str, &'static str)> {
    let mut all = SHADER_MODULES.to_vec();
    all.push(("present.wgsl", harness::viewer::present::PRESENT_WGSL));
    all
}

#[test]
fn every_shader_module_validates_and_covers_every_wgsl_file() {
    let all = all_modules();
    for (name, src) in &all {
        module(name, src);
    }
    let files = shaders();
    assert!(files.len() >= 3, "found {files:?}");
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        assert!(
            all.iter().any(|(_, src)| src.contains(text.trim())),
            "{} is not part of any shader module the renderer compiles",
            f.display()
        );
    }
}

/// (size, [(member, offset)]) of a struct in a module.
fn layout(m: &naga::Module, name: &str) -> (u32, Vec<(String, u32)>) {
    let (_, ty) = m
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("struct {name} not found"));
    match &ty.inner {
        naga::TypeInner::Struct { members, span } => (
            *span,
            members
                .iter()
                .map(|mb| (mb.name.clone().unwrap_or_default(), mb.offset))
                .collect(),
        ),
        other => panic!("{name} is not a struct: {other:?}"),
    }
}

#[test]
fn uniform_structs_match_their_rust_mirrors() {
    let (m, _) = module("splat", SPLAT_WGSL);
    let (size, members) = layout(&m, "Frame");
    assert_eq!(size as usize, std::mem::size_of::<FrameUniform>());
    let expect = [
        ("view_proj", std::mem::offset_of!(FrameUniform, view_proj)),
        ("eye", std::mem::offset_of!(FrameUniform, eye)),
        ("proj_scale", std::mem::offset_of!(FrameUniform, proj_scale)),
        ("viewport", std::mem::offset_of!(FrameUniform, viewport)),
        ("ambient", std::mem::offset_of!(FrameUniform, ambient)),
        ("base_color", std::mem::offset_of!(FrameUniform, base_color)),
        ("view", std::mem::offset_of!(FrameUniform, view)),
        (
            "depth_offset",
            std::mem::offset_of!(FrameUniform, depth_offset),
        ),
    ];
    for (name, off) in expect {
        let got = members.iter().find(|(n, _)| n == name).map(|(_, o)| *o);
        assert_eq!(got, Some(off as u32), "Frame.{name}");
    }
    let (size, members) = layout(&m, "Draw");
    assert_eq!(size as usize, std::mem::size_of::<DrawUniform>());
    let expect = [
        ("size_px", std::mem::offset_of!(DrawUniform, size_px)),
        (
            "radius_scale",
            std::mem::offset_of!(DrawUniform, radius_scale),
        ),
        ("min_px", std::mem::offset_of!(DrawUniform, min_px)),
        ("mode", std::mem::offset_of!(DrawUniform, mode)),
        ("flags", std::mem::offset_of!(DrawUniform, flags)),
        ("test_kind", std::mem::offset_of!(DrawUniform, test_kind)),
        ("test_mode", std::mem::offset_of!(DrawUniform, test_mode)),
        ("test_scale", std::mem::offset_of!(DrawUniform, test_scale)),
        (
            "test_overlap",
            std::mem::offset_of!(DrawUniform, test_overlap),
        ),
        ("count", std::mem::offset_of!(DrawUniform, count)),
        ("slot", std::mem::offset_of!(DrawUniform, slot)),
    ];
    for (name, off) in expect {
        let got = members.iter().find(|(n, _)| n == name).map(|(_, o)| *o);
        assert_eq!(got, Some(off as u32), "Draw.{name}");
    }
}

/// The occlusion-query shader binds the first 64 bytes of the frame uniform buffer as its
/// `QueryFrame`: that must be `view_proj`, at the same offset.
#[test]
fn query_frame_is_the_leading_view_proj_of_the_frame_uniform() {
    let (m, _) = module("occlusion", OCCLUSION_WGSL);
    let (size, members) = layout(&m, "QueryFrame");
    assert_eq!(size, 64);
    assert_eq!(members, vec![("view_proj".to_string(), 0)]);
    assert_eq!(std::mem::offset_of!(FrameUniform, view_proj), 0);
    assert_eq!(std::mem::size_of::<[[f32; 4]; 4]>(), 64);
}
