//! profile.md: one section per profiling tool, each with its status and note.

use std::fmt::Write as _;

use super::{ProfileReport, Row, Section, SizeTiming, Status};
use crate::report::Summary;
use crate::report::Table;
use crate::services::efficiency::RooflineEfficiency;

fn ms(s: &Summary) -> [String; 2] {
    [format!("{:.2}", s.median), format!("{:.2}..{:.2}", s.min, s.max)]
}

fn status<T>(out: &mut String, s: &Section<T>) {
    let word = match s.status {
        Status::Measured => "measured",
        Status::Unsupported => "unsupported",
        Status::NotApplicable => "not applicable",
        Status::Skipped => "skipped",
    };
    let _ = writeln!(out, "Status: **{word}**. {}\n", s.note);
}

fn size_table(rows: &[Row<SizeTiming>], subgroup: bool) -> Table {
    let mut t = Table::new([
        "method",
        "set",
        "rays",
        if subgroup { "subgroup size" } else { "workgroup size" },
        "kernel ms",
        "min..max",
        "Mrays/s",
        "agree %",
        "hits differing from default",
    ]);
    for r in rows {
        let d = &r.data;
        let [med, range] = ms(&d.kernel_ms);
        let size = if subgroup {
            d.subgroup_size.map(|s| s.to_string()).unwrap_or_default()
        } else {
            d.local_size.to_string()
        };
        t.row([
            r.method.to_string(),
            d.ray_set.to_string(),
            d.rays.to_string(),
            size,
            med,
            range,
            format!("{:.2}", d.mrays_per_s),
            format!("{:.4}", 100.0 * d.agreement),
            d.hits_differing_from_default.to_string(),
        ]);
    }
    t
}

/// `profile.md`: the header, then one section per tool, each with its status and rows.
pub fn render(r: &ProfileReport, command: &str) -> String {
    let mut out = header(r, command);
    for section in [
        timestamps,
        pipeline_statistics,
        shader_clock,
        executable_properties,
        size_sweeps,
        lp_threads,
        driver_statistics,
    ] {
        section(&mut out, r);
    }
    out
}

/// The device, host, scene, rays, timing method and command.
fn header(r: &ProfileReport, command: &str) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "# Driver-level profile: {} on {}\n", r.scene, r.tag.device);
    let _ = writeln!(
        out,
        "- **device**: {} ({}), driver {}, Mesa {}\n- **host CPUs**: {}; LP_NUM_THREADS of the profiling process: {}; load average (1, 5, 15 min) before {}, after {}\n\
         - **scene**: {} ({} triangles), leaf size {}, binned SAH, leaf policy `fill`, layout `{}`\n- **rays**: {} (primary: a {}x{} camera image)\n\
         - **timing**: GPU timestamps around each dispatch, {} warm-up run(s), then the median (min..max) of {} runs; \
         every result's hits checked against the f64 reference (at least 99.99% agreement) before it is reported\n\
         - **command**: `{command}`\n",
        r.tag.device,
        r.driver_id,
        r.tag.driver,
        r.tag.mesa_version.as_deref().unwrap_or("-"),
        r.host_cpus,
        r.lp_num_threads.as_deref().unwrap_or("unset (driver default)"),
        r.host_load_before.as_deref().unwrap_or("-"),
        r.host_load_after.as_deref().unwrap_or("-"),
        r.scene,
        r.triangles,
        r.leaf_size,
        r.layout,
        r.ray_sets.iter().map(|(n, c)| format!("{n} {c}")).collect::<Vec<_>>().join(", "),
        r.width,
        r.height,
        r.warmup,
        r.repeat,
    );
    let _ = writeln!(
        out,
        "Every table below ran on this device and driver (each row of `profile.json` also names them).\n"
    );

    out
}

/// 1. Per-dispatch kernel time.
fn timestamps(out: &mut String, r: &ProfileReport) {
    let _ = writeln!(out, "## 1. Per-dispatch kernel time (GPU timestamps)\n");
    status(out, &r.timestamps);
    // `--roofline`: each kernel's fetches per ray and its share of the roofline (as bench's).
    let roofline = r.timestamps.rows.iter().any(|row| row.data.roofline.is_some());
    let mut header = vec!["method", "set", "rays", "dispatches", "kernel ms", "min..max", "Mrays/s", "agree %"];
    if roofline {
        header.extend(crate::services::efficiency::COLUMNS);
    }
    let mut t = Table::new(header);
    for row in &r.timestamps.rows {
        let d = &row.data;
        let [med, range] = ms(&d.kernel_ms);
        let mut cells = vec![
            row.method.to_string(),
            d.ray_set.to_string(),
            d.rays.to_string(),
            d.dispatches.to_string(),
            med,
            range,
            format!("{:.2}", d.mrays_per_s),
            format!("{:.4}", 100.0 * d.agreement),
        ];
        if roofline {
            cells.extend(RooflineEfficiency::cells(d.roofline.as_ref()));
        }
        t.row(cells);
    }
    *out += &t.to_markdown();
    if roofline {
        let _ = writeln!(
            out,
            "
`of roofline %`: (nodes visited + triangles tested per ray, from the kernel's stats variant on the same \
             rays) x Mrays/s over the traversal roofline's Msteps/s (`trilab roofline`) at the scene's bytes on its \
             access path."
        );
    }
}

/// 2. Invocations counted by pipeline statistics.
fn pipeline_statistics(out: &mut String, r: &ProfileReport) {
    let _ = writeln!(out, "\n## 2. Pipeline statistics\n");
    status(out, &r.pipeline_statistics);
    if !r.pipeline_statistics.rows.is_empty() {
        let mut t = Table::new([
            "method",
            "set",
            "rays",
            "workgroup size",
            "workgroups",
            "dispatched invocations",
            "COMPUTE_SHADER_INVOCATIONS",
            "equal",
        ]);
        for row in &r.pipeline_statistics.rows {
            let d = &row.data;
            t.row([
                row.method.to_string(),
                d.ray_set.to_string(),
                d.rays.to_string(),
                d.local_size.to_string(),
                d.workgroups.to_string(),
                d.dispatched.to_string(),
                d.compute_shader_invocations.to_string(),
                if d.dispatched == d.compute_shader_invocations { "yes" } else { "NO" }.to_string(),
            ]);
        }
        *out += &t.to_markdown();
        let _ = writeln!(
            out,
            "\nDispatched invocations = ceil(rays / workgroup size) x workgroup size: the invocations past the \
             last ray start and return at once."
        );
    }
}

/// 3. Shader-clock ticks per ray, and the heat maps.
fn shader_clock(out: &mut String, r: &ProfileReport) {
    let _ = writeln!(out, "\n## 3. Shader clock: ticks per ray\n");
    status(out, &r.shader_clock);
    if !r.shader_clock.rows.is_empty() {
        let mut t = Table::new([
            "method",
            "set",
            "rays",
            "mean",
            "median",
            "p99",
            "min",
            "max",
            "saturated",
            "stepped back",
            "hits differing from closest",
        ]);
        for row in &r.shader_clock.rows {
            let d = &row.data;
            t.row([
                row.method.to_string(),
                d.ray_set.to_string(),
                d.rays.to_string(),
                format!("{:.0}", d.ticks.mean),
                format!("{:.0}", d.ticks.median),
                format!("{:.0}", d.ticks.p99),
                d.ticks.min.to_string(),
                d.ticks.max.to_string(),
                d.ticks.saturated.to_string(),
                d.ticks.stepped_back.to_string(),
                d.hits_differing_from_closest.to_string(),
            ]);
        }
        *out += &t.to_markdown();
        let _ = writeln!(
            out,
            "\nTicks are the driver's shader-clock units (not calibrated here). The clock keeps counting while the \
             thread running a subgroup is descheduled, so max and mean carry such outliers (on a CPU driver, \
             likely preemption by other host work); median and p99 are the robust figures. \
             `saturated`: rays whose end - start did not fit 32 bits (written as 0xFFFFFFFF: the thread was \
             stopped for seconds); `stepped back`: rays whose clock read lower at the end (0xFFFFFFFE: a clock \
             not monotonic across CPUs). Both are counted in the statistics as those values."
        );
        if let Some(s) = &r.heat_scale {
            let _ = writeln!(
                out,
                "\nHeat maps of the primary rays ({}x{}, one pixel per ray): colour is log(ticks), clipped to \
                 [{:.0}, {:.0}] ticks, percentiles p{} and p{} of all methods' primary-ray counts together, \
                 so a colour means the same count in every image (inferno: dark = few ticks, light = many).\n",
                r.width, r.height, s.lo, s.hi, s.percentile_lo, s.percentile_hi
            );
            for row in r.shader_clock.rows.iter().filter(|x| x.data.heat_map.is_some()) {
                let f = row.data.heat_map.as_deref().unwrap_or_default();
                let _ = writeln!(out, "**{}**\n\n![{} ticks per primary ray]({f})\n", row.method, row.method);
            }
        }
    }
}

/// 4. What the driver says it compiled.
fn executable_properties(out: &mut String, r: &ProfileReport) {
    let _ = writeln!(out, "\n## 4. Pipeline executable properties\n");
    status(out, &r.executable_properties);
    if !r.executable_properties.rows.is_empty() {
        let mut t = Table::new(["method", "executable", "subgroup size", "statistic", "value", "description"]);
        for row in &r.executable_properties.rows {
            let d = &row.data;
            t.row([
                row.method.to_string(),
                format!("{} {}", d.executable, d.executable_name),
                d.subgroup_size.to_string(),
                d.name.clone(),
                d.value.clone(),
                d.description.clone(),
            ]);
        }
        *out += &t.to_markdown();
    }
}

/// 5 and 6. The subgroup- and workgroup-size sweeps.
fn size_sweeps(out: &mut String, r: &ProfileReport) {
    let _ = writeln!(out, "\n## 5. Subgroup-size sweep (VK_EXT_subgroup_size_control)\n");
    status(out, &r.subgroup_sizes);
    if !r.subgroup_sizes.rows.is_empty() {
        let _ = writeln!(out, "Ray set: {}; workgroup size {}.\n", r.sweep_set, r.default_local_size);
        *out += &size_table(&r.subgroup_sizes.rows, true).to_markdown();
    }

    let _ = writeln!(out, "\n## 6. Workgroup-size sweep (specialisation constant)\n");
    status(out, &r.workgroup_sizes);
    if !r.workgroup_sizes.rows.is_empty() {
        let _ = writeln!(out, "Ray set: {}; the default is {}.\n", r.sweep_set, r.default_local_size);
        *out += &size_table(&r.workgroup_sizes.rows, false).to_markdown();
    }
}

/// 7. LP_NUM_THREADS scaling.
fn lp_threads(out: &mut String, r: &ProfileReport) {
    let _ = writeln!(out, "\n## 7. LP_NUM_THREADS scaling\n");
    status(out, &r.lp_num_threads_scaling);
    if !r.lp_num_threads_scaling.rows.is_empty() {
        let mut t =
            Table::new(["method", "set", "rays", "LP_NUM_THREADS", "kernel ms", "min..max", "Mrays/s", "vs 1 thread"]);
        let rows = &r.lp_num_threads_scaling.rows;
        let mut sorted: Vec<_> = rows.iter().collect();
        sorted.sort_by(|a, b| {
            (a.method, &a.data.ray_set, a.data.threads).cmp(&(b.method, &b.data.ray_set, b.data.threads))
        });
        for row in sorted {
            let d = &row.data;
            let one = rows
                .iter()
                .find(|x| x.method == row.method && x.data.ray_set == d.ray_set && x.data.threads == 1)
                .map(|x| format!("{:.2}x", d.mrays_per_s / x.data.mrays_per_s))
                .unwrap_or_else(|| "-".into());
            let [med, range] = ms(&d.kernel_ms);
            t.row([
                row.method.to_string(),
                d.ray_set.to_string(),
                d.rays.to_string(),
                d.threads.to_string(),
                med,
                range,
                format!("{:.2}", d.mrays_per_s),
                one,
            ]);
        }
        *out += &t.to_markdown();
    }
}

fn driver_statistics(out: &mut String, r: &ProfileReport) {
    let _ = writeln!(out, "\n## 8. Driver statistics\n");
    status(out, &r.driver_statistics);
    let ks = &r.driver_statistics.rows;
    if ks.iter().any(|k| k.lavapipe.is_some()) {
        *out += &crate::services::driver_stats::table(ks).to_markdown();
        *out += crate::services::driver_stats::LEGEND;
    }
    let compiled: Vec<&crate::services::driver_stats::KernelStats> =
        ks.iter().filter(|k| !k.statistics.is_empty()).collect();
    if !compiled.is_empty() {
        *out += &crate::services::driver_stats::report::compiled_table(&compiled).to_markdown();
        *out += crate::services::driver_stats::report::COMPILED_LEGEND;
    }
}
