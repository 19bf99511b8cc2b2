"""Rule build_env: one procedural environment map (equirect EXR) and its preview."""

from freqbrdf import envmaps
from freqbrdf.io import tonemap, write_exr, write_png
from freqbrdf.logs import run_script


def main(smk, log):
    settings = dict(smk.params.settings)
    kind = settings.pop("kind")
    height = smk.params.height
    if kind == "sunny":
        from freqbrdf.mitsuba_setup import setup_mitsuba
        from freqbrdf.render import sunsky

        mi = setup_mitsuba(threads=smk.threads)
        sun = envmaps.direction_from_angles(settings.get("sun_elevation_deg", 40.0), settings.get("sun_azimuth_deg", 60.0))
        sky = sunsky(mi, height, sun, settings.get("turbidity", 3.0))
        env = envmaps.add_ground(sky, settings.get("ground_albedo", 0.25), settings.get("horizon_blur_deg", 2.0))
    else:
        env = getattr(envmaps, kind)(height, **settings)
    env = envmaps.normalise(env, smk.params.mean_radiance)
    log.info("%s (%s): %s, max radiance %.1f", smk.wildcards.env, kind, env.shape, env.max())
    write_exr(smk.output.exr, env)
    write_png(smk.output.preview, tonemap(env))


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
