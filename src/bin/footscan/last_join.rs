//! `footscan last join`: the toe part of one last joined to the back part of another, by the
//! Gordon surface (docs/method.md section 11) or the blend of morph and extension (section
//! 12), so a last maker can run both on the same lasts and compare the same files and figures.

use anyhow::{bail, Context, Result};
use clap::{Parser, ValueEnum};
use footscan_geom::mesh::{TriMesh, Units};
use footscan_geom::plane::Plane;
use footscan_geom::{P3, V3};
use footscan_last::blend::{self, Blend, BlendParams};
use footscan_last::join::landmarks::{place_pair, Sides};
use footscan_last::join::{self, output, JoinParams};
use footscan_last::outdir::write_dir_atomic;
use footscan_last::size::{check_last_size, check_pair};
use std::path::{Path, PathBuf};

/// How the gap between the two kept parts is closed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Method {
    /// A Gordon surface through the sections of both parts and guide curves across the gap.
    Gordon,
    /// Planar slices blending a linear morph with a G1/G2 extension of both parts.
    Blend,
}

/// How the blend's slices become surfaces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SkinArg {
    One,
    Pieces,
}

#[derive(Parser)]
pub struct JoinArgs {
    /// Last whose back part (heel to the back plane) is kept (STL, OBJ or PLY).
    #[arg(long)]
    back: PathBuf,
    /// Last whose toe part (toe plane to the tip) is kept.
    #[arg(long)]
    toe: PathBuf,
    /// Back cutting plane: `X` (mm along the last in the common frame, the back last's heel
    /// point at 0), `P%` (of the back last's length), or `ox,oy,oz,nx,ny,nz` (normal towards
    /// the toe). Default: 93 % of the way from the back last's heel point to its joint line
    /// (about 62 % of its length), so lasts of different sizes join.
    #[arg(long)]
    back_plane: Option<String>,
    /// Toe cutting plane, as --back-plane (P% of the toe last's length). Default: 10 % of the
    /// way from the joint line to the toe last's toe point (about 70 % of its length). The
    /// blend needs it parallel to the back plane.
    #[arg(long)]
    toe_plane: Option<String>,
    /// How the gap is closed: `gordon` (a Gordon surface on sections and guides) or `blend`
    /// (slices blending a linear morph with an extension of both parts).
    #[arg(long, value_enum, default_value_t = Method::Gordon)]
    method: Method,
    /// Blending function of --method blend: b, the weight of the morph against the
    /// extension at each fill slice. `linear` (0 at both seams, 1 mid-gap), `poly` (the same
    /// with zero slope at both ends and mid-gap), `fair` (b searched for the least curvature
    /// variation of the fill), `fair-energy` (least curvature, for reference), `morph` (1),
    /// `extension` (0), or `table:FILE`: a text file of rows `t b`, t the position across the
    /// gap (0 at the back plane, 1 at the toe plane) strictly increasing, b in [0, 1]; two
    /// numbers per row split by spaces or a comma, `#` starts a comment, at least two rows;
    /// b is linear between rows and constant beyond the first and last.
    #[arg(long, default_value = "poly")]
    blend: String,
    /// Surfaces of --method blend: `one` (one skin through every slice split at the seams,
    /// as the Gordon join splits its surface; the seams are interior) or `pieces` (back part,
    /// fill and toe part skinned apart: the seams show what the fill's slices carry).
    #[arg(long, value_enum, default_value_t = SkinArg::One)]
    skin: SkinArg,
    /// Auxiliary sections on the back and toe sides, `B,T` (or one number for both; gordon).
    #[arg(long, default_value = "2,2")]
    aux: String,
    /// Points per section (default 500 for gordon, 240 per slice for blend).
    #[arg(long)]
    points: Option<usize>,
    /// Rotation angle of the plane bundle that places the guides (gordon) or aligns the
    /// slices (blend), degrees.
    #[arg(long, default_value_t = 45.0)]
    angle: f64,
    /// Units of both meshes: mm, m, or auto (decided from the size).
    #[arg(long, default_value = "auto")]
    units: Units,
    /// Scale both lasts so their length is this many mm (for unitless meshes).
    #[arg(long)]
    length: Option<f64>,
    /// Take the meshes as already placed in a common frame (x heel to toe, z up) instead of
    /// standing each on its tread and superimposing them at the joint line.
    #[arg(long)]
    as_is: bool,
    /// Mirror the toe last onto the back last's side when the two are of different sides
    /// (without it such a pair is refused: a right toe on a left back fits no foot).
    #[arg(long)]
    mirror_toe: bool,
    /// Join two lasts whose lengths differ by more than a size group (13 %).
    #[arg(long)]
    allow_size_mismatch: bool,
    /// Gordon: refit the kept parts to their meshes' facets (within 0.1 mm on the fit's
    /// check grid, 0.16-0.31 mm on a denser one; the section surfaces 0.2-0.9 mm) and keep
    /// the original meshes in the STL; the patch meets them G1 (normal jumps under 0.01 deg,
    /// its tangent changed only in a band next to each seam). Off by default: the fits take
    /// 0.25-1 s per part in a release build (read back from --fit-cache in a few ms).
    #[arg(long)]
    fit_parts: bool,
    /// With --fit-parts: the directory that keeps fitted parts, keyed by the SHA-256 of
    /// everything a fit reads (the part's section surface, the placed mesh, the plane, the
    /// fit's rules), so joining the same lasts again reads the fits instead of making them.
    /// Default $XDG_CACHE_HOME/footscan/fits (else ~/.cache/footscan/fits); `none` fits
    /// every time.
    #[arg(long, value_name = "DIR")]
    fit_cache: Option<PathBuf>,
    /// Output directory (created if missing).
    #[arg(long)]
    out: PathBuf,
}

/// Parse a plane argument against the placed last it cuts.
fn parse_plane(s: &str, placed: &TriMesh, which: &str) -> Result<Plane> {
    let bad = || {
        format!(
            "--{which}-plane {s:?}: expected X (mm along the last), P% (of its length) or \
             ox,oy,oz,nx,ny,nz"
        )
    };
    let b = placed.bbox();
    let across = |x: f64| {
        Plane::with_axis(P3::new(x, 0.5 * (b.min.y + b.max.y), 0.0), V3::x(), V3::y())
            .with_context(bad)
    };
    if let Some(p) = s.strip_suffix('%') {
        let f: f64 = p.trim().parse().ok().with_context(bad)?;
        if !(0.0..=100.0).contains(&f) {
            bail!("{}: the percentage must be 0 to 100", bad());
        }
        return across(b.min.x + f / 100.0 * b.extent().x);
    }
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()
        .with_context(bad)?;
    match v.as_slice() {
        [x] => across(*x),
        [ox, oy, oz, nx, ny, nz] => {
            Plane::new(P3::new(*ox, *oy, *oz), V3::new(*nx, *ny, *nz)).with_context(bad)
        }
        _ => bail!("{}", bad()),
    }
}

pub fn run(a: JoinArgs) -> Result<()> {
    // Arguments first, so a bad word costs no mesh reading.
    let blend = match a.method {
        Method::Blend => Some(Blend::from_arg(&a.blend).context("--blend")?),
        Method::Gordon => None,
    };
    let aux: Vec<usize> = a
        .aux
        .split(',')
        .map(|x| x.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .ok()
        .with_context(|| format!("--aux {:?}: expected B,T or N (whole numbers)", a.aux))?;
    let (aux_back, aux_toe) = match aux.as_slice() {
        [n] => (*n, *n),
        [b, t] => (*b, *t),
        _ => bail!("--aux {:?}: expected B,T or N", a.aux),
    };
    // Each last must have a last's size (a wrong --units makes a 299 m last, whose join
    // grew to gigabytes), and the two a size group apart at most: refused before anything
    // is computed or written.
    let load = |p: &PathBuf| -> Result<(TriMesh, f64)> {
        let m = TriMesh::load_solid(p, a.units, a.length)
            .with_context(|| format!("reading last {}", p.display()))?
            .0;
        let l = check_last_size(p, &m)?;
        Ok((m, l))
    };
    let ((back, back_len), (toe, toe_len)) = (load(&a.back)?, load(&a.toe)?);
    if !a.allow_size_mismatch {
        check_pair((&a.back, back_len), (&a.toe, toe_len))?;
    }
    // Each last stood on its tread as `last measure` and `last adjust` stand it, sides
    // checked, the toe last moved to the back last's joint line (docs/method.md 11.6).
    let (back, toe, mut back_plane, mut toe_plane) = if a.as_is {
        (back, toe, None, None)
    } else {
        let sides = if a.mirror_toe {
            Sides::MirrorToe
        } else {
            Sides::Refuse
        };
        let p = place_pair(
            &back,
            &a.back.display().to_string(),
            &toe,
            &a.toe.display().to_string(),
            sides,
        )?;
        println!(
            "placed: back last {} {} mm, toe last {} {} mm{}, joint lines met at x = {:.1} mm",
            p.back_measures
                .side
                .map_or("(side undecided)", footscan_geom::Side::as_str),
            fmt1(p.back_measures.stick_length),
            p.toe_measures
                .side
                .map_or("(side undecided)", footscan_geom::Side::as_str),
            fmt1(p.toe_measures.stick_length),
            if p.toe_mirrored { " (mirrored)" } else { "" },
            p.joint_x
        );
        (p.back, p.toe, Some(p.back_plane), Some(p.toe_plane))
    };
    let placement = join::Placement::AsIs;
    if let Some(s) = &a.back_plane {
        back_plane = Some(parse_plane(s, &back, "back")?);
    }
    if let Some(s) = &a.toe_plane {
        toe_plane = Some(parse_plane(s, &toe, "toe")?);
    }
    if let (Some(b), Some(t)) = (&back_plane, &toe_plane) {
        println!(
            "planes: back at x = {:.1} mm, toe at x = {:.1} mm",
            b.origin.x, t.origin.x
        );
    }
    let name = format!(
        "{} back + {} toe",
        a.back.file_stem().unwrap_or_default().to_string_lossy(),
        a.toe.file_stem().unwrap_or_default().to_string_lossy()
    );
    if let Some(blend) = blend {
        let p = BlendParams {
            back_plane,
            toe_plane,
            points: a.points.unwrap_or(BlendParams::default().points),
            angle_deg: a.angle,
            placement_back: placement,
            placement_toe: placement,
            blend,
            skin: match a.skin {
                SkinArg::One => blend::Skin::One,
                SkinArg::Pieces => blend::Skin::Pieces,
            },
            ..BlendParams::default()
        };
        return run_blend(&back, &toe, &p, &name, &a);
    }
    let p = JoinParams {
        back_plane,
        toe_plane,
        aux_back,
        aux_toe,
        points: a.points.unwrap_or(JoinParams::default().points),
        angle_deg: a.angle,
        placement_back: placement,
        placement_toe: placement,
        fit_parts: a.fit_parts,
        fit_cache: match &a.fit_cache {
            Some(d) if d.as_os_str() == "none" => None,
            Some(d) => Some(d.clone()),
            None => join::fit_cache::default_dir(),
        },
        ..JoinParams::default()
    };
    let j = join::join(&back, &toe, &p)?;
    let w = write_all_or_nothing(&a.out, |dir| {
        output::write(&j, dir, &name).map(|w| {
            let files = w.files.clone();
            (w, files)
        })
    })?;
    let q = &w.quality;
    let t = &j.timings;
    println!(
        "{name}: gordon, {} sections x {} guides, {} points per section, {} deg",
        j.network.sections.len(),
        j.network.guides.len(),
        p.points,
        a.angle
    );
    println!(
        "join {:.1} ms (place {:.1}, sections {:.1}, curves {:.1}, Gordon {:.1}, split {:.1}, \
         patch to the fitted parts {:.1})",
        t.join, t.place, t.sections, t.curves, t.gordon, t.split, t.meet
    );
    if let Some(f) = &q.fits {
        for ((s, f), ms) in [("back", &f[0]), ("toe", &f[1])]
            .into_iter()
            .zip([t.fit_back, t.fit_toe])
        {
            let how = match (&p.fit_cache, f.cached) {
                (Some(_), true) => format!("read from the fit cache in {ms:.0} ms, fitted"),
                (Some(d), false) => format!("fit cache miss ({}), fitted", d.display()),
                (None, _) => "fitted".to_string(),
            };
            println!(
                "{s} part {how} to its mesh in {:.0} ms: {} facet points, {} fits, {} x {} \
                 spans; max {:.3} mm at ({:.1}, {:.1}, {:.1}), {:.1} mm from the {s} plane; \
                 rms {:.4} mm",
                f.ms,
                f.samples,
                f.rounds,
                f.spans_u,
                f.spans_v,
                f.max_mm,
                f.max_at[0],
                f.max_at[1],
                f.max_at[2],
                f.max_from_plane_mm,
                f.rms_mm
            );
            if f.max_mm > join::keep::TOL_MM {
                println!(
                    "warning: the {s} part stays up to {:.3} mm from its mesh on the fit's check \
                     grid, over the {} mm the fit aims at",
                    f.max_mm,
                    join::keep::TOL_MM
                );
            }
        }
        println!("joined.stl: the original lasts outside the planes, the patch between them");
    }
    print_seams(&[("back", &q.back_seam), ("toe", &q.toe_seam)]);
    print_original(&[("back", &q.back_original), ("toe", &q.toe_original)]);
    println!(
        "the original lasts' own facets within 2.5 mm of the planes meet at {:.2} deg max, \
         {:.2} mean (back), {:.2} max, {:.2} mean (toe)",
        q.back_facets_deg.0, q.back_facets_deg.1, q.toe_facets_deg.0, q.toe_facets_deg.1
    );
    print_deviation(&[("back", &q.back_deviation), ("toe", &q.toe_deviation)]);
    if q.fits.is_some() {
        for (s, d) in [("back", &q.back_deviation), ("toe", &q.toe_deviation)] {
            if d.max_mm > join::keep::TOL_MM {
                println!(
                    "warning: the {s} part's surface in the IGES and STEP files strays {:.3} mm \
                     from its mesh between the fit's check points, over {} mm (where the mesh \
                     bends sharply: docs/method.md 11.7.5)",
                    d.max_mm,
                    join::keep::TOL_MM
                );
            }
        }
    }
    for f in in_out(&a.out, &w.files) {
        println!("wrote {}", f.display());
    }
    Ok(())
}

fn fmt1(x: f64) -> String {
    format!("{x:.1}")
}

/// Writes the output directory through `write` into a fresh sibling and puts it in place
/// only when every file is written: a join that fails half-way leaves --out as it was.
fn write_all_or_nothing<T>(
    out: &Path,
    write: impl FnOnce(&Path) -> std::io::Result<(T, Vec<PathBuf>)>,
) -> Result<T> {
    write_dir_atomic(out, |dir| {
        write(dir)
            .map(|(v, _)| v)
            .map_err(|e| (dir.to_path_buf(), e.to_string()))
    })
    .map_err(|(p, e)| anyhow::anyhow!("writing into {} ({}): {e}", out.display(), p.display()))
}

/// The written files by their names in --out (they were written into its temporary sibling).
fn in_out(out: &Path, files: &[PathBuf]) -> Vec<PathBuf> {
    files
        .iter()
        .map(|f| out.join(f.file_name().unwrap_or_default()))
        .collect()
}

fn print_seams(s: &[(&str, &join::seam::SeamMetrics)]) {
    for (s, m) in s {
        println!(
            "{s} seam: gap {:.1e} mm, normal jump {:.1e} deg, curvature jump {:.1e} (relative)",
            m.gap_max_mm, m.normal_max_deg, m.curvature_rel_max
        );
    }
}

/// The kept parts' ends against the original lasts at the planes.
fn print_original(s: &[(&str, &join::seam::SeamMetrics)]) {
    for (s, m) in s {
        println!(
            "{s} seam against the original {s} last: gap {:.1e} mm, normal {:.2} deg max, \
             {:.2} mean, curvature jump {:.2} (relative) max, {:.2} mean",
            m.gap_max_mm,
            m.normal_max_deg,
            m.normal_mean_deg,
            m.curvature_rel_max,
            m.curvature_rel_mean
        );
    }
}

fn print_deviation(d: &[(&str, &join::seam::Deviation)]) {
    for (s, d) in d {
        println!(
            "{s} part from its mesh: rms {:.3} mm, max {:.3} mm",
            d.rms_mm, d.max_mm
        );
    }
}

fn run_blend(
    back: &TriMesh,
    toe: &TriMesh,
    p: &BlendParams,
    name: &str,
    a: &JoinArgs,
) -> Result<()> {
    let f = blend::fill(back, toe, p)?;
    let q = blend::output::quality(&f, 400)?;
    let w = write_all_or_nothing(&a.out, |dir| {
        blend::output::write_as_join(&f, &q, dir).map(|w| {
            let files = w.files();
            (w, files)
        })
    })?;
    let t = &f.timings;
    let fill_slices = f
        .slices
        .iter()
        .filter(|s| s.piece == blend::Piece::Fill)
        .count();
    println!(
        "{name}: blend {}, gap {:.1} mm filled by {fill_slices} slices {:.2} mm apart, {} points \
         per slice, {} slices in all",
        f.blend,
        f.gap_mm,
        0.5 * f.step_mm,
        f.u.len(),
        f.slices.len()
    );
    println!(
        "fill {:.1} ms (slices {:.1}, blend {:.1}, surfaces {:.1})",
        t.total, t.slices, t.blend, t.surfaces
    );
    if let Some(fr) = &f.fair {
        let b: Vec<String> = fr.table.iter().map(|r| format!("{:.2}", r.1)).collect();
        println!(
            "fairing ({}): b = {} at t = 0, 1/6, ..., 1; {:.3e} against {:.3e} for the morph \
             alone, {} evaluations",
            fr.functional,
            b.join(" "),
            fr.cost,
            fr.cost_morph,
            fr.evaluations
        );
    }
    print_seams(&[("back", &q.back_seam), ("toe", &q.toe_seam)]);
    print_original(&[("back", &q.back_original), ("toe", &q.toe_original)]);
    println!(
        "fill fairness: curvature variation {:.3e} 1/mm^2, curvature energy {:.3e}",
        q.fill_variation, q.fill_energy
    );
    print_deviation(&[("back", &q.back_deviation), ("toe", &q.toe_deviation)]);
    for f in in_out(&a.out, &w.files()) {
        println!("wrote {}", f.display());
    }
    Ok(())
}
