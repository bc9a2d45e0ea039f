//! `pathlight merge`: the partial renders of one render (`render --samples A..B --out
//! PART.part`, e.g. from several machines) combined into its image, exactly.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use clap::Args;
use pathlight_render::output::{write_film, Format};
use pathlight_render::part;

#[derive(Debug, Args)]
pub struct MergeArgs {
    /// The partial renders (.part), in any order: together they must cover the render's
    /// samples 0..spp exactly once.
    #[arg(required = true, value_name = "PART")]
    pub parts: Vec<PathBuf>,

    /// Output image: .png (tone-mapped sRGB) or .exr (linear HDR RGB).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,

    /// With an .exr output: also write the albedo, normal, depth, direct, indirect, variance
    /// and spp layers.
    #[arg(long)]
    pub aovs: bool,
}

pub fn run(args: &MergeArgs) -> Result<()> {
    Format::from_path(&args.out)?;
    let start = Instant::now();
    let (header, film) = part::merge(&args.parts)?;
    write_film(&args.out, &film, args.aovs, &header.config.display)?;
    eprintln!(
        "{}: {}x{} at {} spp from {} parts in {:.2} s",
        args.out.display(),
        header.width,
        header.height,
        header.config.spp,
        args.parts.len(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
