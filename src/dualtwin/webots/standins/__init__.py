"""Our own stand-ins for a few common Webots PROTOs that worlds reference by URL.

The Webots PROTO files are licensed for use with Webots only, so they are not copied here. These
PROTOs were written by us from the documented interface fields (names and defaults of the Webots
reference/objects documentation) and reproduce only what matters for a headless physics twin:

- ``Floor``: a static Solid with a Plane boundingObject (infinite half-space for collision).
- ``RectangleArena``: a Plane floor plus four static walls (Box boundingObjects) around it.
- ``TexturedBackground`` / ``TexturedBackgroundLight``: visual only (a Background / DirectionalLight).

They are used only when the real PROTO file cannot be found on the search path.
"""

from __future__ import annotations

STANDIN_PREFIX = "<dualtwin-standin>/"

_HEADER = "#VRML_SIM R2023b utf8\n# license: Apache-2.0 (dualtwin stand-in, not the Webots asset)\n"

FLOOR = (
    _HEADER
    + """
PROTO Floor [
  field SFVec3f    translation     0 0 0
  field SFRotation rotation        0 0 1 0
  field SFString   name            "floor"
  field SFString   contactMaterial "default"
  field SFVec2f    size            10 10
  field SFVec2f    tileSize        0.5 0.5
  field SFNode     appearance      PBRAppearance { baseColor 0.8 0.8 0.8 roughness 1 metalness 0 }
]
{
  Solid {
    translation IS translation
    rotation IS rotation
    children [
      Shape {
        appearance IS appearance
        geometry Plane { size IS size }
      }
    ]
    name IS name
    model "floor"
    contactMaterial IS contactMaterial
    boundingObject Plane { size IS size }
    locked TRUE
  }
}
"""
)

# Walls sit outside the floor; the two walls along x are longer by 2*thickness to close the corners.
RECTANGLE_ARENA = (
    _HEADER
    + """# template language: javascript
PROTO RectangleArena [
  field SFVec3f    translation     0 0 0
  field SFRotation rotation        0 0 1 0
  field SFString   name            "rectangle arena"
  field SFString   contactMaterial "default"
  field SFVec2f    floorSize       1 1
  field SFVec2f    floorTileSize   0.5 0.5
  field SFNode     floorAppearance PBRAppearance { baseColor 0.8 0.8 0.8 roughness 1 metalness 0 }
  field SFFloat    wallThickness   0.01
  field SFFloat    wallHeight      0.1
  field SFNode     wallAppearance  PBRAppearance { baseColor 0.7 0.7 0.7 roughness 0.4 metalness 0.5 }
]
{
  %<
    const fx = fields.floorSize.value.x;
    const fy = fields.floorSize.value.y;
    const t = fields.wallThickness.value;
    const h = fields.wallHeight.value;
    // [x, y, size x, size y] of the four walls
    const walls = [
      [(fx + t) / 2, 0, t, fy + 2 * t],
      [-(fx + t) / 2, 0, t, fy + 2 * t],
      [0, (fy + t) / 2, fx, t],
      [0, -(fy + t) / 2, fx, t],
    ];
    const names = ['wall', 'wall(1)', 'wall(2)', 'wall(3)'];
  >%
  Solid {
    translation IS translation
    rotation IS rotation
    children [
      Shape {
        appearance IS floorAppearance
        geometry Plane { size IS floorSize }
      }
      %< for (let i = 0; i < 4; ++i) { const w = walls[i]; >%
      Solid {
        translation %<= w[0] >% %<= w[1] >% %<= h / 2 >%
        children [
          Shape {
            appearance IS wallAppearance
            geometry Box { size %<= w[2] >% %<= w[3] >% %<= h >% }
          }
        ]
        name "%<= names[i] >%"
        model "rectangle arena wall"
        contactMaterial IS contactMaterial
        boundingObject Box { size %<= w[2] >% %<= w[3] >% %<= h >% }
        locked TRUE
      }
      %< } >%
    ]
    name IS name
    model "rectangle arena"
    contactMaterial IS contactMaterial
    boundingObject Plane { size IS floorSize }
    locked TRUE
  }
}
"""
)

TEXTURED_BACKGROUND = (
    _HEADER
    + """
PROTO TexturedBackground [
  field SFString texture    "mountains"
  field SFFloat  luminosity 1
  field SFBool   skybox     TRUE
  field MFColor  skyColor   [ 0 0 0 ]
]
{
  Background {
    skyColor IS skyColor
    luminosity IS luminosity
  }
}
"""
)

TEXTURED_BACKGROUND_LIGHT = (
    _HEADER
    + """
PROTO TexturedBackgroundLight [
  field SFString texture     "mountains"
  field SFFloat  luminosity  1
  field SFBool   castShadows TRUE
]
{
  DirectionalLight {
    direction -0.5 -0.6 -1
    intensity IS luminosity
    castShadows IS castShadows
  }
}
"""
)

#: PROTO name -> PROTO file text.
STANDIN_PROTOS: dict[str, str] = {
    "Floor": FLOOR,
    "RectangleArena": RECTANGLE_ARENA,
    "TexturedBackground": TEXTURED_BACKGROUND,
    "TexturedBackgroundLight": TEXTURED_BACKGROUND_LIGHT,
}
