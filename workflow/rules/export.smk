# Exports people can use outside the pipeline (issue 20): every estimate and
# ground truth as binary glTF, the environment maps as Radiance .hdr, and per
# capture an HTML page showing them side by side under any environment.
from freqbrdf.export.viewer import WEB_ASSETS, WEB_DIR

# Every .glb, .hdr and viewer page the export rules write.
EXPORT_TARGETS = (
    [fill(layout.TRUTH_GLTF, object=o) for o in TRUTH_OBJECTS]
    + [fill(layout.GLTF, object=o, env=e, poses=POSES, method=m) for o, e in CAPTURES for m in METHODS]
    + expand(layout.ENVMAP_HDR, env=ENVS)
    + [fill(layout.VIEWER, object=o, env=e, poses=POSES) for o, e in CAPTURES]
)


rule export_gltf:
    """One method's estimate on the capture's mesh as binary glTF 2.0 (metallic-roughness material,
    base colour sRGB-encoded, roughness in G and metallic in B, 8 bits)."""
    input:
        estimate=layout.ESTIMATE,
        mesh=mesh_file,
        code=library("export_gltf"),
    output:
        layout.GLTF,
    log:
        layout.log("export_gltf", "{object}_{env}_{poses}_{method}"),
    benchmark:
        layout.benchmark("export_gltf", "{object}_{env}_{poses}_{method}")
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500, "texels"),
        runtime=minutes(1, "texels"),
    params:
        name=lambda wildcards: wildcards.method,
    script:
        "../scripts/export_gltf.py"


rule export_truth_gltf:
    """A synthetic object's ground-truth textures on its mesh as binary glTF, as rule export_gltf."""
    input:
        **object_files("{object}"),
        code=library("export_truth_gltf"),
    output:
        layout.TRUTH_GLTF,
    log:
        layout.log("export_truth_gltf", "{object}"),
    benchmark:
        layout.benchmark("export_truth_gltf", "{object}")
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500, "texels"),
        runtime=minutes(1, "texels"),
    params:
        name=layout.TRUTH,
    script:
        "../scripts/export_truth_gltf.py"


rule export_env:
    """An environment map as Radiance .hdr (RGBE, Mitsuba's equirectangular layout)."""
    input:
        envmap=layout.ENVMAP,
        code=library("export_env"),
    output:
        layout.ENVMAP_HDR,
    log:
        layout.log("export_env", "{env}"),
    benchmark:
        layout.benchmark("export_env", "{env}")
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500),
        runtime=minutes(1),
    script:
        "../scripts/export_env.py"


rule viewer:
    """The ground truth and every method's .glb side by side in one self-contained HTML page (three.js,
    inlined): one camera for all panels, any benchmark environment, each method's uncertainty (its
    posterior's where it has one) or the entropy as an overlay."""
    input:
        truth=lambda w: [] if w.object in REAL_CAPTURES else [fill(layout.TRUTH_GLTF, object=w.object)],
        estimates=lambda w: [fill(layout.GLTF, object=w.object, env=w.env, poses=w.poses, method=m) for m in METHODS],
        envs=expand(layout.ENVMAP_HDR, env=ENVS),
        sources=asset_sources,
        entropy=layout.ENTROPY,
        posteriors=viewer_posteriors,
        cameras=pose_dir,  # the page opens on the capture's first view
        web=[str(WEB_DIR / asset) for asset in WEB_ASSETS],
        code=library("viewer"),
    output:
        # Linked from the maps figure's caption, not embedded: a single-file report would
        # carry 7 MB per page as data: addresses, which Chromium does not show above 2 MB.
        layout.VIEWER,
    log:
        layout.log("viewer", "{object}_{env}_{poses}"),
    benchmark:
        layout.benchmark("viewer", "{object}_{env}_{poses}")
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500, "texels"),
        runtime=minutes(1, "texels"),
    params:
        panels=viewer_panels,
        posteriors=VIEWER_POSTERIORS,
        envs=ENVS,
        title=lambda w: f"FreqBRDF: {w.object} / {w.env} ({w.poses} poses)",
    script:
        "../scripts/viewer.py"
