// Generated from docs/EXT_materials_cone_step_mapping.schema.json by csm_assets.web.schema_module(); do not edit.
export const SCHEMA = Object.freeze({
 "$schema": "https://json-schema.org/draft/2020-12/schema",
 "title": "EXT_materials_cone_step_mapping material extension",
 "description": "A Cone Step Mapping step map and the settings its shader needs (csm-assets).",
 "type": "object",
 "$defs": {
  "textureInfo": {
   "description": "glTF's textureInfo: a texture's index and the texCoord set it is sampled with (extensions such as KHR_texture_transform allowed).",
   "type": "object",
   "properties": {
    "index": {
     "type": "integer",
     "minimum": 0
    },
    "texCoord": {
     "type": "integer",
     "minimum": 0,
     "default": 0
    }
   },
   "required": [
    "index"
   ]
  }
 },
 "properties": {
  "stepMapTexture": {
   "description": "textureInfo of the packed RGBA step map: R height, G sqrt(cone ratio / maxRatio), B 0.5 + dh/dx, A 0.5 - dh/dy (per texel). Sampled LINEAR without mipmaps; wrap REPEAT on tiled axes, CLAMP_TO_EDGE otherwise.",
   "$ref": "#/$defs/textureInfo"
  },
  "stepMap2Texture": {
   "description": "textureInfo of a quadrant step map's second image: R height, G sqrt(cone ratio of the +u-v quadrant / maxRatio), B 0.5 + dh/dx, A 0.5 - dh/dy; stepMapTexture then holds R height and in G, B, A the cones of the +u+v, -u+v and -u-v quadrants. Present exactly when variant is quadrant. The same texCoord as stepMapTexture, sampled as it (at the same uv, LINEAR without mipmaps, the same wrap); both images have the same size.",
   "$ref": "#/$defs/textureInfo"
  },
  "stepMapLevelsTexture": {
   "description": "Optional. textureInfo of an image holding levels 1..n of stepMapTexture (OpenGL mip sizes: each axis max(1, n / 2 rounded down), down to 1x1) side by side in one row: level 1 at (0, 0), level k at x = the sum of the widths of levels 1..k-1, y = 0; other texels 0. Each level is packed as stepMapTexture is, with exact cones of its own heights (heights 2x2-averaged, or max-filtered, from the level above; B and A averaged, per texel of level 0). An engine may upload them as stepMapTexture's mip levels 1..n; one without this property ignores it. The same texCoord as stepMapTexture. See docs/reference/levels.md.",
   "$ref": "#/$defs/textureInfo"
  },
  "stepMap2LevelsTexture": {
   "description": "Optional. stepMapLevelsTexture's counterpart for stepMap2Texture (quadrant step maps with levels), in the same layout.",
   "$ref": "#/$defs/textureInfo"
  },
  "depthScale": {
   "description": "Depth of the relief in texture space: uv units per unit of height (1 = as deep as the texture is wide).",
   "type": "number",
   "minimum": 0
  },
  "maxRatio": {
   "description": "The cone ratio that G = 1 stands for.",
   "type": "number",
   "exclusiveMinimum": 0,
   "default": 1.0
  },
  "tile": {
   "description": "Whether the cones wrap around along u and v.",
   "type": "array",
   "items": {
    "type": "boolean"
   },
   "minItems": 2,
   "maxItems": 2,
   "default": [
    true,
    true
   ]
  },
  "heightScale": {
   "description": "How the step map's R maps back to the source height texture's values (its normalization): raw = heightOffset + heightScale * R. Not the scene's displacement factor, which depthScale holds.",
   "type": "number",
   "default": 1.0
  },
  "heightOffset": {
   "type": "number",
   "default": 0.0,
   "description": "The normalization's offset: raw = heightOffset + heightScale * R (see heightScale; not a displacement bias)."
  },
  "variant": {
   "description": "Shader variant: exact, loop, fixed, parallax, pom, relief, relaxed or quadrant (quadrant draws a quadrant step map, two images: stepMapTexture and stepMap2Texture; the other variants draw a one-image step map).",
   "type": "string",
   "default": "exact",
   "enum": [
    "exact",
    "loop",
    "fixed",
    "parallax",
    "pom",
    "relief",
    "relaxed",
    "quadrant"
   ]
  },
  "steps": {
   "description": "Steps of the stepped variants (1..127): loop and fixed cone steps, pom and relief linear steps, relaxed search steps; 0 for exact and parallax, which take none.",
   "type": "integer",
   "minimum": 0,
   "default": 0,
   "maximum": 127
  },
  "minStep": {
   "description": "The minimum step in texels of exact, relaxed and the self-shadow march (the paper: 1; 0.25 for bilinear-safe step maps, whose G is the 3x3 minimum).",
   "type": "number",
   "exclusiveMinimum": 0,
   "default": 1.0,
   "maximum": 1
  },
  "selfShadow": {
   "description": "Whether the surface shades itself: a shadow ray from each hit toward the light, stepped with the same cones as the view ray. Omitted when false.",
   "type": "boolean",
   "default": false
  },
  "lightSize": {
   "description": "The light's angular radius in radians for self-shadowing: 0 = hard shadows, > 0 = a soft penumbra. Omitted when 0.",
   "type": "number",
   "minimum": 0,
   "default": 0.0
  }
 },
 "required": [
  "stepMapTexture",
  "depthScale"
 ]
});
