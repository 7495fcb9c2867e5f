//! How the merge's tables and plots name a cell ([`cell_label`]) and a device
//! ([`series_names`]).

use super::Device;
use crate::rows::Cell;

/// A cell's coordinates in reading order: `scene`, `set`, `leaf`, `method`, `layout`, `kernel`,
/// `traversal`, then any other key by name (`scene=bunny leaf=4 method=mt layout=bvh2`).
pub fn cell_label(cell: &Cell) -> String {
    const ORDER: [&str; 7] = ["scene", "set", "leaf", "method", "layout", "kernel", "traversal"];
    let rank = |k: &str| ORDER.iter().position(|o| *o == k).unwrap_or(ORDER.len());
    let mut keys: Vec<&String> = cell.keys().collect();
    keys.sort_by_key(|k| (rank(k), k.as_str()));
    keys.iter().map(|k| format!("{k}={}", cell[*k])).collect::<Vec<_>>().join(" ")
}

/// Short names for the plots' legend, one per device: `D1`, `D2`, ... and what tells the device
/// apart from the others: the settings whose values differ (`LP_NATIVE_VECTOR_WIDTH` as
/// `WIDTH`; `unset` where a device ran without it, its driver's default) and, where those do not tell every device apart, the words of its name that differ
/// from the others' (its whole name when there is one device), cut to fit the legend.
pub fn series_names(devices: &[Device]) -> Vec<String> {
    let mut keys: Vec<&String> = devices.iter().flat_map(|d| d.settings.keys()).collect();
    keys.sort();
    keys.dedup();
    keys.retain(|k| {
        k.as_str() != "LP_NUM_THREADS" && devices.iter().any(|d| d.settings.get(*k) != devices[0].settings.get(*k))
    });
    // The fewest differing settings (in name order) that tell the devices apart, else all.
    let with = |n: usize| -> Vec<String> {
        devices
            .iter()
            .map(|d| {
                keys.iter()
                    .take(n)
                    .map(|k| {
                        let upper = k.chars().any(|c| c.is_ascii_uppercase());
                        let short = if upper { k.rsplit('_').next().unwrap_or(k) } else { k };
                        format!("{short}={}", d.settings.get(*k).map_or("unset", String::as_str))
                    })
                    .collect::<Vec<_>>()
                    .join(", ")
            })
            .collect()
    };
    let distinct = |v: &[String]| {
        let mut d = v.to_vec();
        d.sort();
        d.dedup();
        d.len() == devices.len()
    };
    let n = (1..=keys.len()).find(|&n| distinct(&with(n))).unwrap_or(keys.len());
    let settings = with(n);
    let by_settings = !keys.is_empty() && distinct(&settings);
    // The words of each name between the words every name starts and ends with.
    let words: Vec<Vec<&str>> = devices.iter().map(|d| d.device.split_whitespace().collect()).collect();
    let shortest = words.iter().map(Vec::len).min().unwrap_or(0);
    let prefix = (0..shortest).take_while(|&i| words.iter().all(|w| w[i] == words[0][i])).count();
    let suffix = (0..shortest - prefix)
        .take_while(|&i| words.iter().all(|w| w[w.len() - 1 - i] == words[0][words[0].len() - 1 - i]))
        .count();
    devices
        .iter()
        .enumerate()
        .map(|(i, d)| {
            let mut parts = vec![];
            if !by_settings {
                let own = words[i][prefix..words[i].len() - suffix].join(" ");
                parts.push(if own.is_empty() || devices.len() == 1 { d.device.clone() } else { own });
            }
            if !settings[i].is_empty() {
                parts.push(settings[i].clone());
            }
            let text = parts.join(", ");
            let cut: String = text.chars().take(20).collect();
            let cut = if cut.len() < text.len() { format!("{cut}…") } else { cut };
            format!("D{}: {cut}", i + 1)
        })
        .collect()
}
