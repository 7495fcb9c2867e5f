//! The ray-casting benchmark (`trilab bench`, `cargo bench`): primary, diffuse and random ray
//! sets on each scene, every method, each result validated against the f64 reference before
//! its speed is reported (as tinybvh's speed test does), optionally beside the peers (Embree,
//! tinybvh: `services::peers`) on the same ray files in the same run, each validated the same way.
//!
//! Its room: [`plan`] (options, defaults and the planned cells), [`run`] (the measurement),
//! [`report`] (rows, tables and result rows).

mod plan;
mod report;
mod run;

pub use crate::services::efficiency::RooflineEfficiency;
pub use plan::{plan_cells, BenchCell, BenchOptions, BenchRecipe, CellTracer};
pub use report::{rows, BenchReport, BenchRow, Tracer};
pub use run::{for_device, run};

#[cfg(test)]
mod tests {
    use super::plan::*;
    use super::report::*;

    use std::path::{Path, PathBuf};

    use crate::bvh::NodeOrder;
    use crate::encoding::{AccessPath, Layout, Method, Traversal};

    use crate::gpu::Peer;

    use crate::services::peer_report::{PeerComparison, TrilabBest};
    use crate::services::peers::{EmbreeApi, PeerKind, PeerOutcome};
    use crate::services::provenance::Provenance;
    use crate::services::rayset::{RaySet, RaySetSizes};
    use crate::services::shard::Shard;

    use crate::rays::order::RayOrder;

    use crate::report::Summary;

    #[test]
    fn a_bench_cell_plans_and_rows_with_the_same_coordinates() {
        let method = |sah_group, traversal, order| CellTracer::Method {
            method: Method::Mt,
            layout: Layout::Bvh4,
            leaf: 4,
            sah_group: Some(sah_group),
            traversal,
            node_order: NodeOrder::Built,
            order,
            access: AccessPath::Texel,
        };
        let tracer = method(1, Traversal::WhileIf, RayOrder::Given);
        let planned = BenchCell { scene: "bunny".into(), set: RaySet::Diffuse, rays: None, tracer };
        let measured = BenchCell { rays: Some(9794), ..planned.clone() };
        let want = [("layout", "bvh4"), ("leaf", "4"), ("method", "mt"), ("scene", "bunny"), ("set", "diffuse")];
        let plan = planned.coordinates();
        assert_eq!(plan.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect::<Vec<_>>(), want);
        // The row adds only what is measured, so the plan finds it.
        let row = measured.coordinates();
        assert_eq!(row.get("rays").map(String::as_str), Some("9794"));
        assert!(crate::rows::plan_matches(&plan, &row));
        // A SAH group of 1 is the default and unnamed; another is a coordinate of both.
        let grouped = method(4, Traversal::WhileIf, RayOrder::Given);
        let g = BenchCell { tracer: grouped, ..planned.clone() }.coordinates();
        assert_eq!(g.get("sah_group").map(String::as_str), Some("4"));
        assert!(!crate::rows::plan_matches(&g, &row));
        // So are a traversal other than while-if and a ray order other than the given one.
        let ww =
            BenchCell { tracer: method(1, Traversal::WhileWhile, RayOrder::Given), ..planned.clone() }.coordinates();
        assert_eq!(ww.get("traversal").map(String::as_str), Some("while-while"));
        assert!(!crate::rows::plan_matches(&ww, &row) && !ww.contains_key("order"));
        let sorted = BenchCell { tracer: method(1, Traversal::WhileIf, RayOrder::OctantOrigin), ..planned.clone() }
            .coordinates();
        assert_eq!(sorted.get("order").map(String::as_str), Some("octant-origin"));
        assert!(!crate::rows::plan_matches(&sorted, &row) && !sorted.contains_key("traversal"));
        // And a node order other than the built one.
        let treelets = CellTracer::Method {
            method: Method::Mt,
            layout: Layout::Bvh4,
            leaf: 4,
            sah_group: Some(1),
            traversal: Traversal::WhileIf,
            node_order: NodeOrder::Treelets,
            order: RayOrder::Given,
            access: AccessPath::Texel,
        };
        let t = BenchCell { tracer: treelets, ..planned.clone() }.coordinates();
        assert_eq!(t.get("node_order").map(String::as_str), Some("treelets"));
        assert!(!crate::rows::plan_matches(&t, &row) && !row.contains_key("node_order"));
        let address = CellTracer::Method {
            method: Method::Mt,
            layout: Layout::Bvh4,
            leaf: 4,
            sah_group: Some(1),
            traversal: Traversal::WhileIf,
            node_order: NodeOrder::Built,
            order: RayOrder::Given,
            access: AccessPath::Address,
        };
        let a = BenchCell { tracer: address, ..planned.clone() }.coordinates();
        assert_eq!(a.get("access").map(String::as_str), Some("address"));
        assert!(!crate::rows::plan_matches(&a, &row) && !row.contains_key("access"));
        let peer = BenchCell { tracer: CellTracer::Peer("embree".into()), ..planned }.coordinates();
        assert_eq!(peer.get("peer").map(String::as_str), Some("embree"));
        assert!(!peer.contains_key("method") && !peer.contains_key("leaf"));
    }

    /// A row's coordinates parse back into the cell they came from, whatever coordinates it has;
    /// what no bench cell has is refused by name.
    #[test]
    fn a_bench_cell_parses_back_from_its_coordinates() {
        let tracers = [
            CellTracer::Peer("tinybvh cpu-bvh8".into()),
            CellTracer::Method {
                method: Method::QuadUnit,
                layout: Layout::Cwbvh,
                leaf: 8,
                sah_group: Some(4),
                traversal: Traversal::WhileWhile,
                node_order: NodeOrder::Treelets,
                order: RayOrder::OctantOrigin,
                access: AccessPath::Storage,
            },
            CellTracer::Method {
                method: Method::Mt,
                layout: Layout::Bvh2,
                leaf: 4,
                sah_group: None,
                traversal: Traversal::default(),
                node_order: NodeOrder::default(),
                order: RayOrder::default(),
                access: AccessPath::Texel,
            },
        ];
        for tracer in tracers {
            for rays in [None, Some(19_200)] {
                let cell = BenchCell { scene: "bunny".into(), set: RaySet::Random, rays, tracer: tracer.clone() };
                assert_eq!(BenchCell::parse(&cell.coordinates()), Ok(cell.clone()), "{:?}", cell.coordinates());
            }
        }
        let good = crate::rows::cell([
            ("scene", "bunny"),
            ("set", "primary"),
            ("method", "mt"),
            ("layout", "bvh2"),
            ("leaf", "4"),
        ]);
        assert!(BenchCell::parse(&good).is_ok());
        let with = |k: &str, v: &str| {
            let mut c = good.clone();
            c.insert(k.into(), v.into());
            BenchCell::parse(&c).unwrap_err()
        };
        assert!(with("layout", "bvh3").contains("layout"), "{}", with("layout", "bvh3"));
        assert!(with("colour", "red").contains("`colour` is no bench coordinate"));
        assert!(with("access", "teleport").contains("access=teleport"));
        assert!(with("leaf", "four").contains("leaf=four"));
        let mut no_set = good.clone();
        no_set.remove("set");
        assert_eq!(BenchCell::parse(&no_set).unwrap_err(), "no `set`");
    }

    /// A report as `run` would make it: two kernel rows, the two driver peers, an Embree peer.
    fn report() -> BenchReport {
        let provenance = Provenance {
            device: "llvmpipe (LLVM 15.0.7, 256 bits)".into(),
            driver: "Mesa 25.0.7".into(),
            mesa_version: Some("25.0.7".into()),
            commit: "abc123".into(),
            date: "2025-01-01T00:00:00Z".into(),
            host: crate::host::Host { cpu_model: "test CPU".into(), cpus: 2, ..Default::default() },
            lp_num_threads: None,
            timed_on_gpu: true,
            settings: [("subgroup_size".to_owned(), "8".to_owned())].into(),
            scenes: vec![],
            spirv_compiler: "test compiler",
            driver_package: None,
            compiles_for: None,
        };
        let row = |method: Tracer, layout: Option<Layout>, ms: Summary, agreement: f64| {
            let mr = crate::services::validate::mrays_summary(48_000, ms);
            BenchRow {
                scene: "bunny".into(),
                triangles: 69_451,
                ray_set: RaySet::Diffuse,
                rays: 48_000,
                method,
                leaf_size: layout.map(|_| 4),
                sah_group: layout.map(|_| 1),
                scene_bytes: 3_000_000 + (ms.median * 1000.0) as usize,
                scene_access: layout.map(|_| AccessPath::Texel),
                layout,
                traversal: layout.map(|_| Traversal::WhileIf),
                order: layout.map(|_| RayOrder::Given),
                node_order: layout.map(|_| NodeOrder::Built),
                reorder_ms: None,
                kernel_ms: ms,
                mrays_per_s: mr.median,
                mrays_per_s_min: mr.min,
                mrays_per_s_max: mr.max,
                agreement,
                unexplained_disagreements: 3,
                invalid: 0,
                embree_mrays_per_s: None,
                roofline: None,
                switched: None,
            }
        };
        let s = |median: f64, min: f64, max: f64| Summary { median, min, max, runs: 5 };
        let rows = vec![
            row(Tracer::Method(Method::Mt), Some(Layout::Bvh2), s(10.0, 9.0, 12.0), 0.9999),
            row(Tracer::Method(Method::Mt), Some(Layout::Bvh4), s(7.0, 6.5, 7.5), 0.9998),
            row(Tracer::Peer(Peer::RayQuery), None, s(900.0, 880.0, 950.0), 0.9990),
            row(Tracer::Peer(Peer::RayTracingPipeline), None, s(800.0, 790.0, 850.0), 0.9990),
        ];
        let embree = crate::services::peers::PeerResult {
            peer: PeerKind::Embree(EmbreeApi::Ray1),
            outcome: PeerOutcome::Timed {
                mrays_per_s: 21.5,
                mrays_per_s_min: 20.0,
                mrays_per_s_max: 22.0,
                trace_ms: Summary { median: 48_000.0 / 21.5e3, min: 48_000.0 / 22e3, max: 48_000.0 / 20e3, runs: 5 },
                build_ms: None,
                threads: Some(2),
                agreement: 0.99995,
            },
        };
        let best = TrilabBest::fastest([("mt".to_owned(), Some(Layout::Bvh4), rows[1].mrays_per_s)]);
        let peers = vec![PeerComparison::new("bunny", RaySet::Diffuse, 48_000, best, vec![embree])];
        BenchReport {
            provenance,
            leaf_size: 4,
            recipe: BenchOptions::default().recipe(),
            repeat: 5,
            rows,
            peers,
            accel: vec![],
            driver_notes: vec![],
            notes: vec![],
            shard: None,
            plan: vec![],
        }
    }

    #[test]
    fn every_row_fills_one_planned_cell_peers_included() {
        let o = BenchOptions {
            scenes: vec![PathBuf::from("bunny")],
            axes: crate::matrix::KernelAxes {
                methods: vec![Method::Mt],
                layouts: vec![Layout::Bvh2, Layout::Bvh4],
                ..Default::default()
            },
            ..BenchOptions::default()
        };
        let plan = plan_cells(
            &o,
            &[Peer::RayQuery, Peer::RayTracingPipeline],
            &[PeerKind::Embree(EmbreeApi::Ray1).to_string()],
        );
        // 3 sets x (2 layouts + the two driver rows + Embree).
        assert_eq!(plan.len(), 3 * 5);
        let rows = rows(&report());
        assert_eq!(rows.len(), 5);
        let mut filled = vec![];
        for r in &rows {
            let fits: Vec<&crate::rows::Cell> = plan.iter().filter(|c| crate::rows::plan_matches(c, &r.cell)).collect();
            assert_eq!(fits.len(), 1, "{} fills {fits:?}", r.key());
            filled.push(fits[0].clone());
        }
        filled.dedup();
        assert_eq!(filled.len(), 5, "each row its own planned cell");
        assert!(filled.iter().all(|c| c["set"] == "diffuse"));
        // Without the ray query and peers, and with an empty random set, they are not planned.
        let o = BenchOptions { sizes: RaySetSizes { random_rays: 0, ..o.sizes }, ..o };
        let plan = plan_cells(&o, &[], &[]);
        assert_eq!(plan.len(), 2 * 2);
        assert!(plan.iter().all(|c| c.contains_key("method") && c["set"] != "random"));
    }

    #[test]
    fn peers_are_planned_where_no_kernel_of_the_matrix_runs() {
        // cwbvh has no cooperative kernel: the matrix has no kernel cell, the peers still run.
        let o = BenchOptions {
            scenes: vec![PathBuf::from("bunny")],
            axes: crate::matrix::KernelAxes {
                methods: vec![Method::Mt],
                layouts: vec![Layout::Cwbvh],
                traversals: vec!["coop".parse::<Traversal>().unwrap()],
                ..Default::default()
            },
            ..BenchOptions::default()
        };
        assert!(o.axes.kernels().is_empty());
        let plan = plan_cells(&o, &[], &[PeerKind::Embree(EmbreeApi::Ray1).to_string()]);
        assert_eq!(plan.len(), 3, "Embree on each of the three sets: {plan:?}");
        assert!(plan.iter().all(|c| c.get("peer").map(String::as_str) == Some("embree3")), "{plan:?}");
    }

    #[test]
    fn a_bench_shard_takes_whole_scenes_and_no_more_shards_than_scenes() {
        let shard = |s: &str| Some(s.parse::<Shard>().unwrap());
        let o = BenchOptions {
            scenes: ["a", "b", "c"].map(PathBuf::from).to_vec(),
            shard: shard("2/2"),
            ..Default::default()
        };
        assert!(o.check_shard().is_ok());
        assert_eq!((0..3).map(|i| o.split().runs(i, 0)).collect::<Vec<_>>(), [false, true, false]);
        let e = BenchOptions { shard: shard("4/4"), ..o }.check_shard().unwrap_err().to_string();
        assert!(e.contains("--shard 4/4") && e.contains("3 scene(s)"), "{e}");
    }

    #[test]
    fn rows_carry_every_table_row_and_peer_with_its_figures() {
        let report = report();
        let rows = rows(&report);
        // The report as bench.json has it: the independent path to each figure.
        let json = serde_json::to_value(&report).unwrap();
        let table = json["rows"].as_array().unwrap();
        assert_eq!(rows.len(), table.len() + 1, "every table row and the Embree peer");
        for t in table {
            let row = rows
                .iter()
                .find(|r| {
                    let method = t["method"].as_str().unwrap();
                    r.cell.get("method").or(r.cell.get("peer")).map(String::as_str) == Some(method)
                        && r.cell.get("layout").map(String::as_str) == t["layout"].as_str()
                })
                .unwrap_or_else(|| panic!("no row for {t}"));
            assert_eq!(row.command, "bench");
            assert_eq!(row.cell["scene"], t["scene"].as_str().unwrap());
            assert_eq!(row.cell["set"], t["ray_set"].as_str().unwrap());
            assert_eq!(row.cell["rays"], t["rays"].to_string());
            let f = &row.figures["mrays_per_s"];
            assert_eq!(f.class, crate::rows::Class::Timing);
            assert_eq!(
                (f.median, f.min, f.max),
                (
                    t["mrays_per_s"].as_f64().unwrap(),
                    t["mrays_per_s_min"].as_f64().unwrap(),
                    t["mrays_per_s_max"].as_f64().unwrap()
                )
            );
            assert!(f.min < f.median && f.median < f.max, "a spread from the rounds");
            assert_eq!(f.runs as u64, t["kernel_ms"]["runs"].as_u64().unwrap());
            assert_eq!(row.figures["agreement"].median, t["agreement"].as_f64().unwrap());
            assert_eq!(row.figures["agreement"].class, crate::rows::Class::Correctness);
            assert_eq!(row.figures["unexplained"].median, t["unexplained_disagreements"].as_f64().unwrap());
            assert_eq!(row.figures["scene_bytes"].median, t["scene_bytes"].as_f64().unwrap());
            assert_eq!(row.figures["scene_bytes"].class, crate::rows::Class::Count);
            assert_eq!(row.source.device, json["device"].as_str().unwrap());
            assert_eq!(row.source.settings["subgroup_size"], "8");
        }
        let peer = &json["peers"][0]["peers"][0];
        let e = rows.iter().find(|r| r.cell.get("peer").map(String::as_str) == peer["peer"].as_str()).unwrap();
        assert_eq!(e.figures["mrays_per_s"].median, peer["mrays_per_s"].as_f64().unwrap());
        let f = &e.figures["mrays_per_s"];
        assert_eq!((f.min, f.max, f.runs), (20.0, 22.0, 5), "a peer's rounds, as trilab's rows have them");
        assert_eq!(e.figures["agreement"].median, peer["agreement"].as_f64().unwrap());
        // The rows survive their file format, and the cells are unique.
        let text = crate::rows::to_jsonl(None, &rows);
        let back = crate::rows::parse(Path::new("rows.jsonl"), &text).unwrap();
        assert_eq!(back.rows, rows);
        let keys: std::collections::BTreeSet<String> = rows.iter().map(|r| r.key()).collect();
        assert_eq!(keys.len(), rows.len());
    }

    /// The node order column only where a row's nodes are not in the built order; the JSON
    /// names a row's node order only then too.
    #[test]
    fn the_node_order_column_appears_only_when_an_order_is_not_the_built_one() {
        let mut r = report();
        let before = r.table().to_text();
        assert!(!before.contains("node order"));
        assert!(serde_json::to_value(&r).unwrap()["rows"][0].get("node_order").is_none());
        r.rows[1].node_order = Some(NodeOrder::Treelets);
        let text = r.table().to_text();
        assert!(text.contains("node order") && text.contains("treelets"), "{text}");
        assert_eq!(serde_json::to_value(&r).unwrap()["rows"][1]["node_order"], "treelets");
        assert!(r.rows[1].label(Method::Mt).contains("treelets"));
    }

    #[test]
    fn rates_keep_three_significant_digits_below_one() {
        assert_eq!(super::report::rate(3.667), "3.67");
        assert_eq!(super::report::rate(0.25), "0.250");
        assert_eq!(super::report::rate(0.002688), "0.00269");
    }
}
