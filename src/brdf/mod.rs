//! brdf
