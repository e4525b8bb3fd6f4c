//! The simulated plant's step and pose read-back allocate nothing (seed 003, section 4.2, as a
//! realtime stage will use it): everything is preallocated when the plant is built.

use frond_formats::rig_toml::RigText;
use frond_motion::Rig;
use frond_motion::sim::{PlantSim, WindSpec};

use crate::common;

#[test]
fn sim_step_and_pose_do_not_allocate() {
    let rig = Rig::from_toml_str(include_str!("../../../../rig-files/plants/grass.toml")).unwrap();
    let wind: WindSpec = "speed=12,dir=30,gust=1,seed=4,until=0.5".parse().unwrap();
    let mut sim = PlantSim::from_rig(&rig, wind).unwrap();
    let (bent, allocations) = common::allocations_in(|| {
        let mut bent: f32 = 0.0;
        for _ in 0..1000 {
            sim.step().unwrap();
            let pose = sim.pose();
            bent = bent.max(pose.joints_deg[0][1].abs());
        }
        bent
    });
    assert_eq!(allocations, 0, "allocations during 1000 steps");
    assert!(bent > 1.0, "the wind bent the plant: {bent}");
}
