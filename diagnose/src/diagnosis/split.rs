//! Step 5: the experiments grouped by fundamental and amplitude, and the held-out ones marked.

use maglab_model::experiments::ExperimentInfo;

/// Groups the dynamic experiments and marks the held-out ones (step 5).
pub fn split(infos: &mut [ExperimentInfo], dynamic: &[usize]) -> Result<(), String> {
    let mut order: Vec<usize> = dynamic.to_vec();
    order.sort_by(|&a, &b| infos[a].fundamental_hz.total_cmp(&infos[b].fundamental_hz));
    let mut group = 0usize;
    let mut anchor = infos[order[0]].fundamental_hz;
    for &k in &order {
        if infos[k].fundamental_hz > anchor * 1.05 {
            group += 1;
            anchor = infos[k].fundamental_hz;
        }
        infos[k].frequency_group = group;
    }
    let top_frequency = group;
    let mut amps: Vec<f64> = dynamic.iter().map(|&k| infos[k].amplitude_a).collect();
    amps.sort_by(f64::total_cmp);
    let mut anchors: Vec<f64> = Vec::new();
    for a in amps {
        if anchors.last().is_none_or(|&l| a > l * 1.10 + 1e-12) {
            anchors.push(a);
        }
    }
    let amp_group = |a: f64| anchors.iter().rposition(|&l| a >= l - 1e-12).unwrap_or(0);
    let top_amp = anchors.len() - 1;
    for &k in dynamic {
        let i = &mut infos[k];
        let top = amp_group(i.amplitude_a) == top_amp;
        i.held_out = if top_frequency >= 1 {
            i.frequency_group == top_frequency
                || (top_amp >= 2 && top)
                || (top_amp == 1 && top && i.frequency_group % 2 == 1)
        } else if top_amp >= 1 {
            amp_group(i.amplitude_a) % 2 == 1
        } else {
            false
        };
    }
    if top_frequency == 0 && top_amp == 0 {
        for (r, &k) in order.iter().enumerate() {
            infos[k].held_out = r % 2 == 1;
        }
    }
    let held = dynamic.iter().filter(|&&k| infos[k].held_out).count();
    if held == 0 || held == dynamic.len() {
        return Err("could not split the experiments into training and held-out sets".into());
    }
    Ok(())
}
