# Exports people can use outside the pipeline (issue 20): every estimate and
# ground truth as binary glTF, the environment maps as Radiance .hdr, and per
# capture an HTML page showing them side by side under any environment.
from freqbrdf.export.viewer import WEB_ASSETS, WEB_DIR

TRUTH_GLTF = "truth"  # node and material name of the ground truth in .glb files and the viewer


rule export_gltf:
    """One method's estimate on the capture's mesh as binary glTF 2.0 (metallic-roughness material,
    base colour sRGB-encoded, roughness in G and metallic in B, 8 bits)."""
    input:
        estimate="results/estimates/{object}/{env}/{poses}/{method}",
        mesh=mesh_file,
        code=library("export_gltf"),
    output:
        "results/gltf/{object}/{env}/{poses}/{method}.glb",
    log:
        "results/logs/export_gltf/{object}_{env}_{poses}_{method}.log",
    benchmark:
        "results/benchmarks/export_gltf/{object}_{env}_{poses}_{method}.tsv"
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500, "texels"),
        runtime=minutes(1, "texels"),
    params:
        name=lambda wildcards: wildcards.method,
    script:
        "../workflow/scripts/export_gltf.py"


rule export_truth_gltf:
    """A synthetic object's ground-truth textures on its mesh as binary glTF, as rule export_gltf."""
    input:
        **object_files("{object}"),
        code=library("export_gltf"),
    output:
        f"results/gltf/{{object}}/{TRUTH_GLTF}.glb",
    log:
        "results/logs/export_truth_gltf/{object}.log",
    benchmark:
        "results/benchmarks/export_truth_gltf/{object}.tsv"
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500, "texels"),
        runtime=minutes(1, "texels"),
    params:
        name=TRUTH_GLTF,
    script:
        "../workflow/scripts/export_gltf.py"


rule export_env:
    """An environment map as Radiance .hdr (RGBE, Mitsuba's equirectangular layout)."""
    input:
        envmap="results/envs/{env}.exr",
        code=library("export_env"),
    output:
        "results/envs/{env}.hdr",
    log:
        "results/logs/export_env/{env}.log",
    benchmark:
        "results/benchmarks/export_env/{env}.tsv"
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500),
        runtime=minutes(1),
    script:
        "../workflow/scripts/export_env.py"


rule viewer:
    """The ground truth and every method's .glb side by side in one self-contained HTML page (three.js,
    inlined): one camera for all panels, any benchmark environment, the entropy as an overlay."""
    input:
        truth=lambda w: [] if w.object in REAL_CAPTURES else [f"results/gltf/{w.object}/{TRUTH_GLTF}.glb"],
        estimates=lambda w: [f"results/gltf/{w.object}/{w.env}/{w.poses}/{m}.glb" for m in METHODS],
        envs=expand("results/envs/{env}.hdr", env=ENVS),
        entropy="results/entropy/{object}/{env}/{poses}",
        cameras=pose_dir,  # the page opens on the capture's first view
        web=[str(WEB_DIR / asset) for asset in WEB_ASSETS],
        code=library("make_viewer"),
    output:
        # Linked from the maps figure's caption, not embedded: a single-file report would
        # carry 7 MB per page as data: addresses, which Chromium does not show above 2 MB.
        "results/viewer/{object}/{env}/{poses}/viewer.html",
    log:
        "results/logs/viewer/{object}_{env}_{poses}.log",
    benchmark:
        "results/benchmarks/viewer/{object}_{env}_{poses}.tsv"
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500, "texels"),
        runtime=minutes(1, "texels"),
    params:
        panels=viewer_panels,
        envs=ENVS,
        title=lambda w: f"FreqBRDF: {w.object} / {w.env} ({w.poses} poses)",
    script:
        "../workflow/scripts/make_viewer.py"
