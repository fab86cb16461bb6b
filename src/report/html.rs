//! The HTML page of a report: one self-contained document (no network: SVG inline, images as
//! `data:` URIs) rendered from [`ReportData`]. Pure: every string from the data is escaped;
//! charts are the SVG documents made by [`super::charts`], inlined. A small inline script marks
//! `<body>` after load with whether every image decoded, for headless-browser tests.

use super::avail::Avail;
use super::gather::{
    CalibrationEntry, ComparisonRow, ComponentsSection, LadderSection, ReportData, TrialsSection,
};
use super::images::EmbeddedImage;
use super::materials::{MaterialDetail, MaterialsSection};
use super::numbers::fmt_num;
use super::session::CaptureSummary;
use crate::geometry::labels::label_colour;
use base64::Engine;
use std::fmt::Write as _;

/// Escapes text for HTML element content and attribute values.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

const STYLE: &str = "body{font-family:sans-serif;max-width:1100px;margin:1em auto;padding:0 1em;\
color:#222}h1{font-size:1.5em}h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}\
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ddd;padding:.2em .6em;\
text-align:left;vertical-align:top}th{background:#f4f4f4}.na{color:#a33;font-style:italic}\
.note{background:#fff8e0;border-left:4px solid #e0b000;padding:.4em .8em}\
.warn li{color:#8a4b00}.conf-low{background:#fdd;padding:.3em}.conf-medium{background:#ffe9b3;padding:.3em}.conf-high{background:#dfd;padding:.3em}figure{display:inline-block;margin:.4em;vertical-align:top}\
figcaption{font-size:.8em;max-width:320px}.charts{display:flex;flex-wrap:wrap;gap:.5em}\
.charts figure{margin:0}.charts svg{max-width:100%;height:auto}\
pre{background:#f7f7f7;padding:.5em;overflow:auto;max-height:20em}.chosen{background:#e8f4e8}\
.hole{display:inline-block;width:200px;height:200px;border:2px dashed #c66;color:#a33;\
padding:1em;box-sizing:border-box}.swatch{display:inline-block;width:1em;height:1em;\
border:1px solid #888;vertical-align:middle;margin-right:.4em}";

/// After load, marks `<body>` with `data-images-ok` (every image decoded) and counts, so a
/// headless browser test can check the page rendered.
const SCRIPT: &str = "window.addEventListener('load',function(){var im=document.images;\
var ok=true;for(var i=0;i<im.length;i++){if(!(im[i].complete&&im[i].naturalWidth>0)){ok=false;}}\
document.body.setAttribute('data-images-ok',ok?'true':'false');\
document.body.setAttribute('data-images',String(im.length));\
document.body.setAttribute('data-svgs',String(document.querySelectorAll('svg').length));});";

fn na(html: &mut String, why: &str) {
    let _ = write!(html, "<p class=\"na\">not available: {}</p>", escape(why));
}

fn kv_table(html: &mut String, rows: &[(String, String)]) {
    html.push_str("<table>");
    for (k, v) in rows {
        let _ = write!(
            html,
            "<tr><th>{}</th><td>{}</td></tr>",
            escape(k),
            escape(v)
        );
    }
    html.push_str("</table>");
}

fn figure(html: &mut String, img: &EmbeddedImage) {
    let b64 = base64::engine::general_purpose::STANDARD.encode(&img.png);
    let _ = write!(
        html,
        "<figure><img src=\"data:image/png;base64,{b64}\" width=\"{}\" height=\"{}\" alt=\"{}\">\
         <figcaption>{}</figcaption></figure>",
        img.width,
        img.height,
        escape(&img.caption),
        escape(&img.caption)
    );
}

fn fmt_vec(v: &[f64]) -> String {
    let parts: Vec<String> = v.iter().map(|x| fmt_num(*x)).collect();
    format!("({})", parts.join(", "))
}

/// The page. Pure: everything comes from `data`, every string in it is escaped; charts are the
/// SVG documents made by [`super::charts`], inlined.
pub fn render_html(data: &ReportData) -> String {
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\
         <title>{}</title><style>{STYLE}</style></head><body>\n",
        escape(&data.title)
    );
    let _ = writeln!(
        h,
        "<h1>{}</h1><p>Folder <code>{}</code>: {}.</p>",
        escape(&data.title),
        escape(&data.dir),
        escape(&data.kinds.join(", "))
    );
    if let Some((level, reasons)) = &data.confidence {
        let _ = write!(
            h,
            "<p id=\"confidence\" class=\"conf-{}\">Confidence in the result: <b>{}</b>",
            escape(level),
            escape(level)
        );
        if reasons.is_empty() {
            h.push_str(
                " (trials agree, the fit explains held-back pixels, theta_d well covered).</p>",
            );
        } else {
            h.push_str("</p><ul class=\"warn\">");
            for r in reasons {
                let _ = write!(h, "<li>{}</li>", escape(r));
            }
            h.push_str("</ul>");
        }
    }
    section_capture(&mut h, &data.capture);
    section_calibration(&mut h, &data.calibration);
    section_brdf(&mut h, data);
    section_ladder(&mut h, &data.ladder);
    if let Some(n) = &data.normals {
        section_normals(&mut h, n);
    }
    if let Some(m) = &data.materials {
        section_materials(&mut h, m);
    }
    section_comparisons(&mut h, &data.comparisons, data.materials.as_ref());
    section_trials(&mut h, &data.trials, &data.components);
    section_timing(&mut h, &data.timing);

    h.push_str("<h2 id=\"warnings\">Warnings</h2>");
    if data.warnings.is_empty() {
        h.push_str("<p>None recorded.</p>");
    } else {
        h.push_str("<ul class=\"warn\">");
        for w in &data.warnings {
            let _ = write!(h, "<li>{}</li>", escape(w));
        }
        h.push_str("</ul>");
    }
    if !data.other_facts.is_empty() {
        h.push_str("<h2 id=\"other\">Other facts from report.json</h2><table>");
        for (k, v) in &data.other_facts {
            let _ = write!(
                h,
                "<tr><th>{}</th><td><pre>{}</pre></td></tr>",
                escape(k),
                escape(v)
            );
        }
        h.push_str("</table>");
    }
    let _ = write!(
        h,
        "\n<p><small>Made by brdf-rig {} (<code>brdf-rig report</code>).</small></p>\
         <script>{SCRIPT}</script>\n</body></html>\n",
        env!("CARGO_PKG_VERSION")
    );
    h
}

fn section_capture(h: &mut String, capture: &Avail<CaptureSummary>) {
    h.push_str("<h2 id=\"capture\">Capture</h2>");
    let c = match capture {
        Avail::No(why) => return na(h, why),
        Avail::Yes(c) => c,
    };
    let mut rows: Vec<(String, String)> = vec![("session folder".into(), c.dir.clone())];
    rows.extend(c.facts.iter().cloned());
    rows.push(("shots".into(), c.shots.to_string()));
    let kinds: Vec<String> = c.by_kind.iter().map(|(k, n)| format!("{k}: {n}")).collect();
    rows.push(("shots by kind".into(), kinds.join(", ")));
    let angles = if c.angles_deg.is_empty() {
        "none recorded".to_string()
    } else if c.angles_deg.len() <= 24 {
        let a: Vec<String> = c.angles_deg.iter().map(|x| fmt_num(*x)).collect();
        format!("{} angles: {}", c.angles_deg.len(), a.join(", "))
    } else {
        format!(
            "{} angles from {} to {} deg",
            c.angles_deg.len(),
            fmt_num(c.angles_deg[0]),
            fmt_num(c.angles_deg[c.angles_deg.len() - 1])
        )
    };
    rows.push(("turntable angles (deg)".into(), angles));
    if let Some(e) = c.max_angle_error_deg {
        rows.push((
            "largest |measured - asked| angle".into(),
            format!("{} deg", fmt_num(e)),
        ));
    }
    let ch: Vec<String> = c
        .channels
        .iter()
        .map(|(k, (n, d))| match d {
            Some(d) => format!(
                "channel {k}: {n} shots, nominal lab direction {}",
                fmt_vec(d)
            ),
            None => format!("channel {k}: {n} shots"),
        })
        .collect();
    rows.push((
        "light channels".into(),
        if ch.is_empty() {
            "none recorded".into()
        } else {
            ch.join("; ")
        },
    ));
    if let (Some(a), Some(b), Some(s)) = (&c.first_utc, &c.last_utc, c.span_secs) {
        rows.push(("time span".into(), format!("{a} to {b} ({} s)", fmt_num(s))));
    }
    if let Some((lo, hi)) = c.exposure_secs {
        rows.push((
            "exposure (s)".into(),
            format!("{} to {}", fmt_num(lo), fmt_num(hi)),
        ));
    }
    kv_table(h, &rows);
    h.push_str("<h3>Checksums</h3>");
    match &c.checksums {
        Avail::No(why) => na(h, why),
        Avail::Yes(st) => {
            let verdict = if st.problems.is_empty() {
                "all intact"
            } else {
                "PROBLEMS"
            };
            let _ = write!(
                h,
                "<p data-checksums=\"{}\">{verdict}: {} of {} files match their recorded size and \
                 SHA-256.</p>",
                if st.problems.is_empty() { "ok" } else { "bad" },
                st.ok,
                st.checked
            );
            if !st.problems.is_empty() {
                h.push_str("<ul class=\"warn\">");
                for p in st.problems.iter().take(50) {
                    let _ = write!(h, "<li>{}</li>", escape(p));
                }
                if st.problems.len() > 50 {
                    let _ = write!(h, "<li>... {} more</li>", st.problems.len() - 50);
                }
                h.push_str("</ul>");
            }
        }
    }
    h.push_str("<h3>Single-light images</h3>");
    match &c.thumbnails {
        Avail::No(why) => na(h, why),
        Avail::Yes(imgs) => {
            h.push_str("<p>Previews (sRGB, auto exposure per image), not data.</p><div>");
            for i in imgs {
                figure(h, i);
            }
            h.push_str("</div>");
        }
    }
}

fn section_calibration(h: &mut String, cal: &Avail<Vec<CalibrationEntry>>) {
    h.push_str("<h2 id=\"calibration\">Calibration</h2>");
    let entries = match cal {
        Avail::No(why) => return na(h, why),
        Avail::Yes(e) => e,
    };
    h.push_str(
        "<table><tr><th>source</th><th>light direction</th><th>uncertainty</th>\
         <th>irradiance</th><th>other</th></tr>",
    );
    for e in entries {
        let dir = e
            .light_dir
            .map(|d| fmt_vec(&d))
            .unwrap_or_else(|| "-".into());
        let unc = e
            .uncertainty_deg
            .map(|u| format!("{} deg", fmt_num(u)))
            .unwrap_or_else(|| "-".into());
        let irr = match (&e.irradiance, &e.irradiance_std_error) {
            (Some(i), Some(s)) => format!("{} +- {}", fmt_vec(i), fmt_vec(s)),
            (Some(i), None) => fmt_vec(i),
            _ => "-".into(),
        };
        let other: Vec<String> = e.other.iter().map(|(k, v)| format!("{k}: {v}")).collect();
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td><small>{}</small></td></tr>",
            escape(&e.source),
            escape(&dir),
            escape(&unc),
            escape(&irr),
            escape(&other.join("; "))
        );
    }
    h.push_str("</table>");
}

fn section_ladder(h: &mut String, ladder: &Avail<LadderSection>) {
    h.push_str("<h2 id=\"ladder\">Model: chosen by held-out image error</h2>");
    match ladder {
        Avail::No(why) => na(h, why),
        Avail::Yes(l) => {
            let _ = write!(
                h,
                "<p>Reported model: <b>{}</b>. {}</p><p>Every model was fitted to the reliable \
                 pixels and scored on pixels it did not see ({}): the relative error of the \
                 re-rendered pixels in log space (of ln(1 + I / s), s the fold's median pixel) and \
                 of their linear values, each the mean over folds +- standard error. The simplest \
                 model within noise of the best is reported, by the error the reason names.</p>",
                escape(&l.model),
                escape(&l.reason),
                escape(&l.scheme)
            );
            ladder_table(h, &l.rows);
            if !l.plausibility.is_empty() {
                h.push_str("<h3>Plausibility of the written table</h3>");
                kv_table(h, &l.plausibility);
            }
        }
    }
}

/// A ladder's rungs as a table, the chosen one marked (nothing when there are none).
fn ladder_table(h: &mut String, rows: &[super::gather::LadderRow]) {
    if rows.is_empty() {
        return;
    }
    h.push_str(
        "<table class=\"ladder\"><tr><th>model</th><th>parameters</th>\
         <th>held-out error, log space</th><th>+- SE</th>\
         <th>held-out error, linear</th><th>+- SE</th><th></th></tr>",
    );
    let num = |x: Option<f64>| x.map(fmt_num).unwrap_or_else(|| "-".into());
    for r in rows {
        let _ = write!(
            h,
            "<tr{}><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            if r.chosen { " class=\"chosen\"" } else { "" },
            escape(&r.label),
            escape(&num(r.parameters)),
            escape(&num(r.error_log)),
            escape(&num(r.standard_error_log)),
            escape(&num(r.error)),
            escape(&num(r.standard_error)),
            if r.chosen { "chosen" } else { "" }
        );
    }
    h.push_str("</table>");
}

fn section_normals(h: &mut String, n: &super::gather::NormalsSection) {
    h.push_str("<h2 id=\"normals\">Normals refined from the images</h2>");
    let num = |x: Option<f64>| x.map(fmt_num).unwrap_or_else(|| "-".into());
    let _ = write!(
        h,
        "<p>The mesh's normals were <b>{}</b>: {}. Held-out light images (they never moved a \
         normal): {}. Normals returned: mean tilt {} deg, largest {} deg, over {} vertices; \
         with the refined normals when accepted, <code>mesh_refined.ply</code> is beside this \
         report's <code>report.json</code>. Errors: mean robust log residual of the pixels \
         (docs/normal-refinement.md); iteration 0 is the start the held-out images chose (the \
         mesh's own normals, or them with the mesh's positions Taubin-smoothed).</p>",
        if n.accepted { "refined" } else { "kept" },
        escape(&n.reason),
        escape(&n.held_out_images),
        escape(&num(n.mean_tilt_deg)),
        escape(&num(n.max_tilt_deg)),
        n.vertices_refined
            .map_or("-".to_string(), |v| v.to_string()),
    );
    if !n.starts.is_empty() {
        let _ = write!(
            h,
            "<p>Starts tried (Taubin steps of the mesh's positions: held-out error): {}.</p>",
            escape(&n.starts)
        );
    }
    let _ = write!(
        h,
        "<p>Reflectance table of the refinement: {}.</p>",
        escape(&n.table)
    );
    if !n.rows.is_empty() {
        h.push_str("<table><tr><th>iteration</th><th>mean tilt (deg)</th><th>largest tilt (deg)</th><th>training error</th><th>held-out error</th><th></th></tr>");
        for r in &n.rows {
            let chosen = n.accepted && Some(r.iteration) == n.chosen_iterations;
            let _ = write!(
                h,
                "<tr{}><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                if chosen { " class=\"chosen\"" } else { "" },
                r.iteration,
                escape(&num(r.mean_tilt_deg)),
                escape(&num(r.max_tilt_deg)),
                escape(&num(r.train_error)),
                escape(&num(r.held_out_error)),
                if chosen { "chosen" } else { "" }
            );
        }
        h.push_str("</table>");
    }
}

/// A small square of a material's colour (`geometry::labels::label_colour`).
fn swatch(h: &mut String, label: usize) {
    let c = label_colour(u32::try_from(label).unwrap_or(u32::MAX));
    let _ = write!(
        h,
        "<span class=\"swatch\" style=\"background:rgb({},{},{})\"></span>",
        c[0], c[1], c[2]
    );
}

fn section_materials(h: &mut String, section: &MaterialsSection) {
    let m = &section.file;
    h.push_str("<h2 id=\"materials\">Materials</h2>");
    let num = |x: Option<f64>| x.map(fmt_num).unwrap_or_else(|| "-".into());
    let _ = write!(
        h,
        "<p><b>{} material(s)</b>: {}. Each count was tried on folds of whole light images \
         (labels from the training images; one reflectance shape shared by the object \
         times a colour per material, fitted to them; error on the held-out images); the \
         simplest count within noise (or 5 %) of the best is kept (docs/materials.md).</p>",
        m.count,
        escape(&m.reason)
    );
    h.push_str("<table><tr><th>count tried</th><th>found</th><th>held-out image error</th><th>standard error</th></tr>");
    for s in &m.scores {
        let _ = write!(
            h,
            "<tr{}><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            if s.found == m.count && s.error.is_some() {
                " class=\"chosen\""
            } else {
                ""
            },
            s.asked,
            s.found,
            escape(&num(s.error)),
            escape(&num(s.standard_error))
        );
    }
    h.push_str("</table>");
    if m.materials.is_empty() {
        return;
    }
    let _ = write!(
        h,
        "<p>One BRDF per material, each chosen by its own model ladder; the largest is also \
         <code>brdf.binary</code>. <code>{}</code> beside <code>report.json</code> is the mesh \
         with each vertex's material (<code>label</code>, 0 = the first row, and the colour \
         shown here, also the colour of the material map beside each re-render).</p>",
        escape(&m.material_map)
    );
    h.push_str("<table><tr><th></th><th>material</th><th>pixels</th><th>vertices</th><th>colour of its pixels (r, g, b shares)</th><th>model</th><th>confidence</th><th>held-out error</th><th>file</th></tr>");
    for (i, e) in m.materials.iter().enumerate() {
        h.push_str("<tr><td>");
        swatch(h, i);
        let _ = write!(
            h,
            "</td><td><a href=\"#material-{}\">{}</a></td><td>{}</td><td>{}</td><td>{:.3}, {:.3}, {:.3}</td><td>{}</td><td>{}</td><td>{}</td><td><code>{}</code></td></tr>",
            i + 1,
            escape(&e.name),
            e.observed_pixels,
            e.observed_vertices,
            e.chromaticity[0],
            e.chromaticity[1],
            e.chromaticity[2],
            escape(&e.model),
            escape(&e.confidence),
            escape(&num(e.held_out_error)),
            escape(&e.file)
        );
    }
    h.push_str("</table>");
    for (i, e) in m.materials.iter().enumerate() {
        section_material(h, i, e, section.details.get(i));
    }
}

/// One material's own section: its facts, its BRDF on spheres and its pixels per light image.
fn section_material(
    h: &mut String,
    i: usize,
    e: &crate::reconstruct::materials::MaterialEntry,
    detail: Option<&MaterialDetail>,
) {
    let num = |x: Option<f64>| x.map(fmt_num).unwrap_or_else(|| "-".into());
    let _ = write!(
        h,
        "<section class=\"material\" id=\"material-{}\"><h3>",
        i + 1
    );
    swatch(h, i);
    let _ = write!(h, "{}</h3>", escape(&e.name));
    // the reasons name their level themselves ("medium: ...")
    let why_confidence = if e.confidence_reasons.is_empty() {
        "trials agree, the fit explains held-back pixels, theta_d well covered".to_string()
    } else {
        e.confidence_reasons.join("; ")
    };
    kv_table(
        h,
        &[
            ("label in material_map.ply".into(), i.to_string()),
            ("observed pixels".into(), e.observed_pixels.to_string()),
            (
                "left out of its fit".into(),
                if e.boundary_pixels > 0 {
                    format!(
                        "{} pixels on faces across a boundary with another material, or of another material's colour near it (they may mix the two, or be the other material's)",
                        e.boundary_pixels
                    )
                } else {
                    "none".to_string()
                },
            ),
            ("observed vertices".into(), e.observed_vertices.to_string()),
            (
                "found by".into(),
                match e.mask_label {
                    Some(l) => format!(
                        "the job's label masks (label {l}; {} vertices fixed by them, the rest \
                         joined by the segmentation)",
                        e.mask_vertices
                    ),
                    None => "the segmentation (no label mask names it)".into(),
                },
            ),
            (
                "colour of its pixels (r, g, b shares)".into(),
                format!(
                    "{:.3}, {:.3}, {:.3}",
                    e.chromaticity[0], e.chromaticity[1], e.chromaticity[2]
                ),
            ),
            ("model".into(), e.model.clone()),
            ("why this model".into(), e.model_reason.clone()),
            ("confidence".into(), e.confidence.clone()),
            ("why this confidence".into(), why_confidence),
            ("held-out error".into(), num(e.held_out_error)),
            ("file".into(), e.file.clone()),
        ],
    );
    // its own ladder and plausibility step (materials.json files before session 37 have none)
    if let Some(l) = &e.ladder {
        let _ = write!(
            h,
            "<p>Its model ladder ({}): every model fitted to this material's reliable pixels \
             and scored on its pixels it did not see, as in the model section above.</p>",
            escape(&super::gather::ladder_scheme(l))
        );
        ladder_table(h, &super::gather::ladder_rows(l));
    }
    if let Some(p) = &e.plausibility {
        h.push_str("<p>Plausibility of its written table:</p>");
        kv_table(h, &super::gather::plausibility_rows(p));
    }
    let Some(d) = detail else {
        na(h, "internal: no details gathered for this material");
        h.push_str("</section>");
        return;
    };
    match &d.spheres {
        Avail::No(why) => {
            na(h, why);
            h.push_str("<div class=\"hole\">sphere renders not available</div>");
        }
        Avail::Yes(imgs) => {
            h.push_str(
                "<p>Its BRDF on the spheres of the result's section (same view and lights; \
                 its own exposure).</p><div>",
            );
            for img in imgs {
                figure(h, img);
            }
            h.push_str("</div>");
        }
    }
    if !d.comparisons.is_empty() {
        h.push_str(
            "<table><tr><th>light image</th><th>its pixels there</th>\
             <th>error of the re-render on them</th></tr>",
        );
        for c in &d.comparisons {
            let _ = write!(
                h,
                "<tr><td><a href=\"#compare-{}\">{}</a></td><td>{}</td><td>{}</td></tr>",
                c.image,
                c.image,
                c.observed_pixels,
                escape(&num(c.fit_error))
            );
        }
        h.push_str("</table>");
    }
    h.push_str("</section>");
}

fn section_comparisons(
    h: &mut String,
    rows: &Avail<Vec<ComparisonRow>>,
    materials: Option<&MaterialsSection>,
) {
    h.push_str("<h2 id=\"compare\">Photo against re-render</h2>");
    match rows {
        Avail::No(why) => na(h, why),
        Avail::Yes(rows) => {
            h.push_str(
                "<p>Each light image (left), the mesh re-rendered with the recovered BRDF from \
                 the same camera, light and irradiance (middle; dark grey where no pixel was \
                 used: background, shadow, grazing or clipped), and the difference (right: red \
                 where the re-render is brighter, blue where darker, on the photo's scale). \
                 No ground truth is needed to read it.</p>",
            );
            if let Some(m) = materials.filter(|m| !m.file.materials.is_empty()) {
                h.push_str(
                    "<p id=\"material-map-legend\">Several materials: each pixel is \
                     re-rendered with its own material's BRDF, and a fourth image is the \
                     material map of the view, each observed pixel in its material's colour \
                     (the colours of <code>material_map.ply</code>), shaded as the re-render; \
                     dark grey where no pixel was used. ",
                );
                for (i, e) in m.file.materials.iter().enumerate() {
                    swatch(h, i);
                    let _ = write!(h, "{} ", escape(&e.name));
                }
                h.push_str("</p>");
            }
            for r in rows {
                let _ = write!(h, "<div id=\"compare-{}\">", r.index);
                figure(h, &r.image);
                h.push_str("</div>");
                let num = |x: Option<f64>| x.map(fmt_num).unwrap_or_else(|| "-".into());
                let _ = write!(
                    h,
                    "<p class=\"note\">Error of the re-render on this image: {}; while this \
                     image was held out from the fit: {}.</p>",
                    escape(&num(r.fit_error)),
                    escape(&num(r.held_out_error))
                );
            }
        }
    }
}

fn section_brdf(h: &mut String, data: &ReportData) {
    h.push_str("<h2 id=\"brdf\">Recovered BRDF: in-plane plot</h2>");
    match &data.brdf {
        Avail::No(why) => na(h, why),
        Avail::Yes(b) => {
            let _ = write!(
                h,
                "<p>From <code>{}</code>. {}. f_r in 1/sr without the cosine factor.</p>",
                escape(&b.file),
                escape(&b.description)
            );
            for p in &data.provenance {
                let _ = write!(h, "<p class=\"note\">Provenance: {}</p>", escape(p));
            }
            if b.uses_neural_fit {
                h.push_str(
                    "<p class=\"note\">Curves marked \"neural MERL fit\" are smooth neural \
                     approximations of the MERL measurements (Sztrajman et al. 2021), not \
                     measured MERL data; they are smoother at specular peaks and grazing \
                     angles.</p>",
                );
            }
            h.push_str("<div class=\"charts\">");
            for svg in &b.charts {
                let _ = write!(h, "<figure class=\"chart\">{svg}</figure>");
            }
            h.push_str("</div>");
            h.push_str("<table><tr><th>curve</th><th>peak red</th><th>peak green</th><th>peak blue</th></tr>");
            for (label, p) in &b.peaks {
                let cell = |x: Option<f64>| {
                    x.map(|a| format!("{} deg", fmt_num(a)))
                        .unwrap_or_else(|| "-".into())
                };
                let _ = write!(
                    h,
                    "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                    escape(label),
                    escape(&cell(p[0])),
                    escape(&cell(p[1])),
                    escape(&cell(p[2]))
                );
            }
            h.push_str("</table>");
            for m in &b.missing {
                let _ = write!(
                    h,
                    "<p class=\"na\">comparison not available: {}</p>",
                    escape(m)
                );
            }
        }
    }
    h.push_str("<h2 id=\"spheres\">Spheres rendered with the result</h2>");
    match &data.spheres {
        Avail::No(why) => {
            na(h, why);
            h.push_str("<div class=\"hole\">sphere renders not available</div>");
        }
        Avail::Yes(imgs) => {
            h.push_str(
                "<p>A unit sphere seen from 4 units away, one directional light; the same \
                 exposure for every light.</p><div>",
            );
            for i in imgs {
                figure(h, i);
            }
            h.push_str("</div>");
        }
    }
    h.push_str("<h3>Renders written by the reconstruction</h3>");
    match &data.renders {
        Avail::No(why) => na(h, why),
        Avail::Yes(imgs) => {
            h.push_str("<div>");
            for i in imgs {
                figure(h, i);
            }
            h.push_str("</div>");
        }
    }
}

fn section_trials(h: &mut String, trials: &Avail<TrialsSection>, comps: &Avail<ComponentsSection>) {
    h.push_str("<h2 id=\"trials\">Trials and their similarities</h2>");
    match trials {
        Avail::No(why) => na(h, why),
        Avail::Yes(t) => {
            let chosen_row = t.chosen.and_then(|c| t.rows.iter().find(|r| r.index == c));
            match (t.chosen, chosen_row) {
                (Some(c), Some(r)) => {
                    let _ = write!(
                        h,
                        "<p id=\"chosen\">Chosen trial: <b>#{c}</b>, cosine similarity <b>{}</b> \
                         (highest of {} trials).</p>",
                        r.similarity
                            .map(fmt_num)
                            .unwrap_or_else(|| "unknown".into()),
                        t.rows.len()
                    );
                }
                (Some(c), None) => {
                    let _ = write!(
                        h,
                        "<p class=\"na\">Chosen trial #{c} is not among the listed trials.</p>"
                    );
                }
                (None, _) => na(h, "report.json names no chosen trial (\"chosen_trial\")"),
            }
            let mut other_keys: Vec<String> = t
                .rows
                .iter()
                .flat_map(|r| r.other.iter().map(|(k, _)| k.clone()))
                .collect();
            other_keys.sort();
            other_keys.dedup();
            h.push_str("<table><tr><th>trial</th><th>similarity</th>");
            for k in &other_keys {
                let _ = write!(h, "<th>{}</th>", escape(k));
            }
            h.push_str("</tr>");
            for r in &t.rows {
                let cls = if Some(r.index) == t.chosen {
                    " class=\"chosen\""
                } else {
                    ""
                };
                let _ = write!(
                    h,
                    "<tr{cls}><td>#{}</td><td>{}</td>",
                    r.index,
                    r.similarity.map(fmt_num).unwrap_or_else(|| "-".into())
                );
                for k in &other_keys {
                    let v = r
                        .other
                        .iter()
                        .find(|(kk, _)| kk == k)
                        .map(|(_, v)| v.as_str())
                        .unwrap_or("-");
                    let _ = write!(h, "<td>{}</td>", escape(v));
                }
                h.push_str("</tr>");
            }
            h.push_str("</table><div class=\"charts\">");
            for svg in &t.charts {
                let _ = write!(h, "<figure class=\"chart\">{svg}</figure>");
            }
            h.push_str("</div>");
        }
    }
    h.push_str("<h2 id=\"components\">Basis components k</h2>");
    match comps {
        Avail::No(why) => na(h, why),
        Avail::Yes(c) => {
            let _ = write!(
                h,
                "<p id=\"k\">k chosen: <b>{}</b></p>",
                c.k.map(|k| k.to_string())
                    .unwrap_or_else(|| "not recorded".into())
            );
            if !c.other.is_empty() {
                kv_table(h, &c.other);
            }
            if let Some(svg) = &c.chart {
                let _ = write!(
                    h,
                    "<div class=\"charts\"><figure class=\"chart\">{svg}</figure></div>"
                );
            }
        }
    }
}

fn section_timing(h: &mut String, timing: &Avail<Vec<(String, f64)>>) {
    h.push_str("<h2 id=\"timing\">Time per stage</h2>");
    match timing {
        Avail::No(why) => na(h, why),
        Avail::Yes(t) => {
            let total: f64 = t.iter().map(|(_, s)| s).sum();
            h.push_str("<table><tr><th>stage</th><th>seconds</th><th>share</th></tr>");
            for (name, s) in t {
                let share = if total > 0.0 { 100.0 * s / total } else { 0.0 };
                let _ = write!(
                    h,
                    "<tr><td>{}</td><td>{}</td><td>{:.0} %</td></tr>",
                    escape(name),
                    fmt_num(*s),
                    share
                );
            }
            let _ = write!(
                h,
                "<tr><th>total</th><th>{}</th><th></th></tr></table>",
                fmt_num(total)
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escape_covers_text_and_attributes() {
        assert_eq!(
            escape(r#"<a href="x">Tom & 'Jerry'</a>"#),
            "&lt;a href=&quot;x&quot;&gt;Tom &amp; &#39;Jerry&#39;&lt;/a&gt;"
        );
        assert_eq!(escape("plain é"), "plain é");
    }
}
