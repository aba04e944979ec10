//! Camera views of a simulated torso (`presets/torso.urdf`): its head camera sees a target on
//! each hand. Writes `examples/torso/views.csv` (60 views of each hand) and `views-2.csv` (40
//! held-out views of each) of a "real" torso whose every joint origin is off by about 1 mm and
//! 0.3 deg, the views with noise of 0.2 mm and 0.05 deg. The camera looks forward and 20 deg
//! down; a view is taken only where it sees the hand's target: within its 70 deg field of
//! view, 200 to 1200 mm away, the target at most 60 deg off facing it.
//!
//! ```text
//! cargo run --release --example make_torso_data
//! cargo run --release -- calibrate --model presets/torso.urdf \
//!     --data examples/torso/views.csv --validate examples/torso/views-2.csv
//! ```

use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use robocal::calibration::tree::TreeData;
use robocal::model::RobotTree;
use robocal::simulation::Sight;
use robocal::simulation::tree::{
    head_camera_and_hands, perturbed_tree, seen_configurations, simulate_views, views_csv,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let nominal = RobotTree::from_urdf_str(include_str!("../presets/torso.urdf"), None, &[])?;
    let mut rng = ChaCha8Rng::seed_from_u64(2026);
    let truth = perturbed_tree(&nominal, 1.0, 0.3f64.to_radians(), &mut rng);
    let (frames, placements) = head_camera_and_hands(&nominal);
    let sigma = [0.2, 0.05f64.to_radians()];
    std::fs::create_dir_all("examples/torso")?;
    let sight =
        Sight { half_angle: 35f64.to_radians(), range: [200.0, 1200.0], incidence: 60f64.to_radians() };
    for (file, poses) in [("views.csv", 60), ("views-2.csv", 40)] {
        let mut data = TreeData::default();
        for pair in [(0, 1), (0, 2)] {
            let q = seen_configurations(&truth, &frames, &placements, pair, &sight, poses, &mut rng)
                .ok_or("the head camera never sees a hand")?;
            data = data.join(&simulate_views(&truth, &frames, &placements, &[pair], &q, sigma, &mut rng))?;
        }
        let path = format!("examples/torso/{file}");
        std::fs::write(&path, views_csv(&nominal, &data))?;
        println!("{path}: {} views at {} poses", data.views.len(), data.joints.len());
    }
    Ok(())
}
