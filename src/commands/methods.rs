//! `trilab methods`: the intersectors in the registry, what each is and what it needs. The
//! README's method list is this report's Markdown (`trilab methods --markdown`, checked by
//! `tests/readme.rs`).

use serde::Serialize;

use crate::encoding::{AccessPath, Method, Raycast};
use crate::report::{Report, Table};

/// One intersector.
#[derive(Clone, Debug, Serialize)]
pub struct MethodInfo {
    pub method: Method,
    pub title: &'static str,
    /// `glsl/intersect/<glsl>.glsl`.
    pub glsl: &'static str,
    pub about: &'static str,
    /// One of Shumskiy & Parshin's four.
    pub in_paper: bool,
    /// Triangles its primitive test takes at once (the GLSL's `PRIM_TRIANGLES`).
    pub triangles_per_test: usize,
    /// Whether it traverses with the conservative box test (the GLSL's `CONSERVATIVE_TRAVERSAL`).
    pub conservative_traversal: bool,
    /// Bytes of its primitive struct.
    pub prim_bytes: usize,
    /// Optional device features its ray-casting kernel needs (from the SPIR-V's capabilities).
    pub needs: Vec<&'static str>,
}

/// Every method in registry order (serialised as the list).
#[derive(Clone, Debug, Serialize)]
#[serde(transparent)]
pub struct MethodsReport {
    pub methods: Vec<MethodInfo>,
}

pub fn run() -> MethodsReport {
    let methods = Method::ALL
        .iter()
        .map(|&m| {
            let i = m.intersector();
            let k = m.raycast_kernel(Raycast::Closest, AccessPath::Texel);
            let needs = crate::spirv::required_features(&k.words()).unwrap_or_default();
            MethodInfo {
                method: m,
                title: i.title,
                glsl: i.glsl,
                about: i.about,
                in_paper: i.in_paper,
                triangles_per_test: m.group_size(),
                conservative_traversal: m.conservative_traversal(),
                prim_bytes: i.prim_struct.size,
                needs: needs.iter().map(|r| r.feature.name()).collect(),
            }
        })
        .collect();
    MethodsReport { methods }
}

impl MethodsReport {
    /// The README's list: one line per method, `- `name`: about`.
    pub fn markdown(&self) -> String {
        self.methods.iter().map(|m| format!("- `{}`: {}\n", m.method, m.about)).collect()
    }
}

impl Report for MethodsReport {
    fn to_text(&self) -> String {
        let mut t =
            Table::new(["method", "title", "glsl", "paper", "triangles/test", "conservative", "prim bytes", "needs"]);
        for m in &self.methods {
            t.row([
                m.method.to_string(),
                m.title.to_string(),
                format!("intersect/{}.glsl", m.glsl),
                if m.in_paper { "yes" } else { "-" }.to_string(),
                m.triangles_per_test.to_string(),
                if m.conservative_traversal { "yes" } else { "-" }.to_string(),
                m.prim_bytes.to_string(),
                if m.needs.is_empty() { "-".to_string() } else { m.needs.join(", ") },
            ]);
        }
        t.to_text()
    }
}
