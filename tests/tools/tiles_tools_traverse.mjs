#!/usr/bin/env node
// Reads a 3D Tiles tileset with 3d-tiles-tools (npm `3d-tiles-tools`): a folder holding
// `tileset.json`, or a `.3tz` archive. Traverses every tile (explicit or implicit: the tools
// expand subtrees and apply the tile metadata semantics, `TILE_BOUNDING_BOX` and
// `TILE_GEOMETRIC_ERROR`), without following external tilesets, and reads every content.
//
// Usage: node tiles_tools_traverse.mjs TILESET (a folder or a .3tz)
// Prints one JSON report on stdout: { "entries": N, "tiles": [{ "path", "level", "parent",
// "box", "geometric_error", "refine", "contents": [{ "uri", "bytes", "md5" }] }] } (a content
// uri template of the implicit root as the tools visit it: { "uri", "template": true }), tiles in
// depth-first order, `parent` the parent's `path` (null at the root). Exit status 0 when the
// script ran, 2 when it could not run (the message on stderr).
import crypto from 'node:crypto';
import {
  TilesetSources,
  TilesetSourceResourceResolver,
  TilesetTraverser,
} from '3d-tiles-tools';

const input = process.argv[2];
if (!input) {
  console.error('usage: tiles_tools_traverse.mjs TILESET');
  process.exit(2);
}
try {
  const source = await TilesetSources.createAndOpen(input);
  let entries = 0;
  for await (const _ of await source.getKeys()) entries += 1;
  const json = await source.getValue('tileset.json');
  if (!json) throw new Error(`${input}: no tileset.json`);
  const tileset = JSON.parse(json.toString('utf8'));
  const resolver = new TilesetSourceResourceResolver('.', source);
  const traverser = new TilesetTraverser('.', resolver, {
    depthFirst: true,
    traverseExternalTilesets: false,
  });
  const tiles = [];
  await traverser.traverse(tileset, async (t) => {
    const f = t.asFinalTile();
    const contents = [];
    for (const c of t.getFinalContents()) {
      if (c.uri.includes('{')) {
        // The implicit root as written in tileset.json: a template, not a file.
        contents.push({ uri: c.uri, template: true });
        continue;
      }
      const data = await source.getValue(c.uri);
      if (!data) throw new Error(`content ${c.uri} of tile ${t.path} not found`);
      contents.push({
        uri: c.uri,
        bytes: data.length,
        md5: crypto.createHash('md5').update(data).digest('hex'),
      });
    }
    const parent = t.getParent();
    tiles.push({
      path: t.path,
      level: t.level,
      parent: parent ? parent.path : null,
      box: f.boundingVolume.box ?? null,
      geometric_error: f.geometricError,
      refine: f.refine ?? null,
      contents,
    });
    return true;
  });
  await source.close();
  process.stdout.write(JSON.stringify({ entries, tiles }) + '\n');
} catch (e) {
  console.error(`3d-tiles-tools: ${e && e.stack ? e.stack : e}`);
  process.exit(2);
}
