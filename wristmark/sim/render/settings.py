"""Image-synthesis settings (noise, blur, JPEG, motion blur, supersampling), loadable from YAML."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from wristmark.models.config_io import from_mapping, load_layered
from wristmark.models.errors import ConfigError

SHADINGS = ("phong", "flat")


@dataclass(frozen=True)
class RenderSettings:
    """How the synthetic endoscope images are degraded. Defaults: a realistic endoscope.

    read_noise: read-noise sigma [grey levels]; shot_gain: shot-noise variance per grey level
    [grey levels]; blur_sigma: optics blur sigma [px]; jpeg_quality: JPEG round trip (1-100) or
    None; motion_blur: length of a linear motion blur [px] (0 = off); supersampling: samples per
    pixel along each axis around the marker (anti-aliasing: sub-pixel corner truth);
    arm_supersampling: the same for the rest of the arm; vignetting: brightness lost at the image corners
    (0-1); adaptive_supersampling: supersample only the pixels whose neighbourhood changes
    surface or curves its shading (edges, corners, silhouettes, highlights), the others take
    their centre ray (within 0.1 grey levels of full supersampling, about half the rays);
    colour: BGR images if true, else grayscale; shading: 'phong' (coaxial light, Lambert plus
    specular, inverse-square falloff) or 'flat' (albedo only: pure geometry, for tests).
    Glossy sleeve (docs/notes/highlight-stripe.md): sleeve_specular: Fresnel reflectance F0 at
    normal incidence of a clear laminate over the sleeve's print (0: off, the matte sleeve of
    today's renders; 0.04: a plastic laminate), whose GGX lobe adds a highlight stripe along the
    sleeve where its surface faces the lights, clipped by the sensor at 255;
    sleeve_roughness: the laminate's GGX roughness alpha (0.03 mirror-like .. 0.3 satin);
    light_offset: distance [m] of the light outputs from each lens centre (two outputs per lens,
    above and below it along the camera's y axis, both lenses' outputs lighting both views; 0:
    one output at each lens centre). Only with shading 'phong'.
    """

    read_noise: float = 1.5
    shot_gain: float = 0.06
    blur_sigma: float = 0.8
    jpeg_quality: int | None = None
    motion_blur: float = 0.0
    supersampling: int = 3
    arm_supersampling: int = 1
    vignetting: float = 0.35
    adaptive_supersampling: bool = True
    colour: bool = True
    shading: str = "phong"
    sleeve_specular: float = 0.0
    sleeve_roughness: float = 0.1
    light_offset: float = 0.0

    def validate(self) -> None:
        """Raise ConfigError naming the offending key."""
        for k in ("read_noise", "shot_gain", "blur_sigma", "motion_blur"):
            if getattr(self, k) < 0:
                raise ConfigError(f"'{k}' must be >= 0, got {getattr(self, k)}")
        if self.jpeg_quality is not None and not 1 <= self.jpeg_quality <= 100:
            raise ConfigError(f"'jpeg_quality' must be in 1..100 or null, got {self.jpeg_quality}")
        for k in ("supersampling", "arm_supersampling"):
            if not 1 <= getattr(self, k) <= 8:
                raise ConfigError(f"'{k}' must be in 1..8, got {getattr(self, k)}")
        if self.shading not in SHADINGS:
            raise ConfigError(f"'shading' must be one of {', '.join(SHADINGS)}, got '{self.shading}'")
        if not 0 <= self.sleeve_specular <= 1:
            raise ConfigError(f"'sleeve_specular' must be in [0, 1], got {self.sleeve_specular}")
        if not 0.01 <= self.sleeve_roughness <= 1:
            raise ConfigError(f"'sleeve_roughness' must be in [0.01, 1], got {self.sleeve_roughness}")
        if not 0 <= self.light_offset <= 0.01:
            raise ConfigError(f"'light_offset' must be in [0, 0.01] m, got {self.light_offset}")
        if not 0 <= self.vignetting < 1:
            raise ConfigError(f"'vignetting' must be in [0, 1), got {self.vignetting}")

    @classmethod
    def load(cls, path: str | Path) -> RenderSettings:
        """Load and validate a render-settings YAML."""
        return from_mapping(cls, load_layered(path), str(path))


NOISE_PRESETS: dict[str, RenderSettings] = {
    "none": RenderSettings(read_noise=0.0, shot_gain=0.0),
    "default": RenderSettings(),
    "strong": RenderSettings(read_noise=4.0, shot_gain=0.25, blur_sigma=1.4),
}


def noise_preset(name: str, **overrides: object) -> RenderSettings:
    """A named preset ('none', 'default', 'strong') with optional field overrides, validated."""
    if name not in NOISE_PRESETS:
        raise ConfigError(f"unknown noise preset '{name}' (valid: {', '.join(NOISE_PRESETS)})")
    s = replace(NOISE_PRESETS[name], **overrides)  # type: ignore[arg-type]
    s.validate()
    return s
