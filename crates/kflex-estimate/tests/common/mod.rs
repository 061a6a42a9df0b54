pub mod fusion_scenario;
