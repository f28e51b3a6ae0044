use maglab_identify::actuator::LagCorrection;
use maglab_identify::design::Grid;
use maglab_identify::memory::InitialState;
use maglab_identify::model::PreisachModel;
fn main() {
    let path = std::env::args().nth(1).unwrap();
    let m = maglab_identify::data::load_measurement(std::path::Path::new(&path)).unwrap();
    let p = actuator_params::paper_defaults();
    let grid = Grid {
        h_min: p.preisach.h_min_a_per_m,
        h_max: p.preisach.h_max_a_per_m,
    };
    let model = PreisachModel::from_weights(
        grid,
        &p.preisach.weights_a_per_m,
        InitialState::NegativeSaturation,
    );
    let a = &p.actuator;
    let s = a.rod_length_m * a.saturation_magnetostriction;
    let ms = a.saturation_magnetization_a_per_m;
    let offset = 1e-6;
    for corr in [false, true] {
        let h: Vec<f64> = if corr {
            // M from the true model to drive the field correction
            let h0: Vec<f64> = m
                .current_a
                .iter()
                .map(|i| a.coil_factor_per_m * i)
                .collect();
            let mt = model.predict(&h0, InitialState::NegativeSaturation);
            LagCorrection::new(&p, [70.0, 0.7783, 392.0]).field(&m.current_a, &mt, m.step_s)
        } else {
            m.current_a
                .iter()
                .map(|i| a.coil_factor_per_m * i)
                .collect()
        };
        let mp = model.predict(&h, InitialState::NegativeSaturation);
        let y: Vec<f64> = m.displacement_m.iter().map(|v| v - offset).collect();
        let u: Vec<f64> = if corr {
            LagCorrection::new(&p, [70.0, 0.7783, 392.0]).displacement(&y, m.step_s)
        } else {
            y.clone()
        };
        let yp: Vec<f64> = mp.iter().map(|mm| s * (mm / ms).powi(2)).collect();
        let rms =
            (u.iter().zip(&yp).map(|(a, b)| (a - b).powi(2)).sum::<f64>() / u.len() as f64).sqrt();
        let worst = u
            .iter()
            .zip(&yp)
            .enumerate()
            .map(|(k, (a, b))| (k, (a - b).abs()))
            .fold((0, 0.0), |x, y| if y.1 > x.1 { y } else { x });
        println!("correction {corr}: rms {:.3} um ({:.3} % of stroke), worst {:.3} um at sample {} (I {:.3} A)", rms * 1e6, 100.0 * rms / s, worst.1 * 1e6, worst.0, m.current_a[worst.0]);
    }
}
