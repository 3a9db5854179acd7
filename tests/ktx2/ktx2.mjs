// Outside reference for our BC6H KTX2 files: Don McCurdy's ktx-parse (pinned in package.json).
//
//   node ktx2.mjs read FILE.ktx2
//       prints the container as ktx-parse sees it, as one JSON object on stdout.
//   node ktx2.mjs flat FILE.ktx2
//       the same facts as `path=value` lines (e.g. `dfd.samples.0.bitLength=127`), which the
//       Rust test reads without a JSON parser.
//   node ktx2.mjs write OUT.ktx2 VKFORMAT WIDTH HEIGHT SIGNED(0|1) PRIMARIES LEVEL0.bin [LEVEL1.bin ...]
//       writes a KTX2 file with ktx-parse's own serializer and a BC6H data format descriptor
//       filled in here (colorPrimaries = PRIMARIES, a khr_df_primaries_e value), from raw block
//       data files (level 0 first).
import { createHash } from 'node:crypto';
import { readFileSync, writeFileSync } from 'node:fs';
import { read, write } from 'ktx-parse';

// Khronos Data Format Specification 1.3: KHR_DF_MODEL_BC6H = 133, transfer LINEAR = 1, sample qualifiers FLOAT = 0x80 and SIGNED = 0x40 (in channelType).
const MODEL_BC6H = 133;
const FLOAT = 0x80;
const SIGNED = 0x40;

function describe(path) {
  const c = read(new Uint8Array(readFileSync(path)));
  const dfd = c.dataFormatDescriptor[0];
  // Raw 32-bit patterns of the float limits (ktx-parse returns signed ints for SIGNED samples).
  const u32 = (v) => Number(v) >>> 0;
  return {
    vkFormat: c.vkFormat,
    typeSize: c.typeSize,
    pixelWidth: c.pixelWidth,
    pixelHeight: c.pixelHeight,
    pixelDepth: c.pixelDepth,
    layerCount: c.layerCount,
    faceCount: c.faceCount,
    levelCount: c.levelCount,
    supercompressionScheme: c.supercompressionScheme,
    levels: c.levels.map((l) => ({
      byteLength: l.levelData.byteLength,
      uncompressedByteLength: Number(l.uncompressedByteLength),
      sha256: createHash('sha256').update(l.levelData).digest('hex'),
      hex: Buffer.from(l.levelData).toString('hex'),
    })),
    dfd: {
      vendorId: dfd.vendorId,
      descriptorType: dfd.descriptorType,
      versionNumber: dfd.versionNumber,
      colorModel: dfd.colorModel,
      colorPrimaries: dfd.colorPrimaries,
      transferFunction: dfd.transferFunction,
      flags: dfd.flags,
      texelBlockDimension: dfd.texelBlockDimension,
      bytesPlane: dfd.bytesPlane,
      samples: dfd.samples.map((s) => ({
        bitOffset: s.bitOffset,
        bitLength: s.bitLength,
        channelType: s.channelType,
        samplePosition: s.samplePosition,
        sampleLower: u32(s.sampleLower),
        sampleUpper: u32(s.sampleUpper),
      })),
    },
    keyValue: Object.fromEntries(
      Object.entries(c.keyValue).map(([k, v]) => [k, typeof v === 'string' ? v : Buffer.from(v).toString('hex')]),
    ),
  };
}

function build(out, vkFormat, width, height, signed, primaries, levelFiles) {
  const c = {
    vkFormat,
    typeSize: 1,
    pixelWidth: width,
    pixelHeight: height,
    pixelDepth: 0,
    layerCount: 0,
    faceCount: 1,
    levelCount: levelFiles.length,
    supercompressionScheme: 0,
    levels: levelFiles.map((f) => {
      const levelData = new Uint8Array(readFileSync(f));
      return { levelData, uncompressedByteLength: levelData.byteLength };
    }),
    dataFormatDescriptor: [
      {
        vendorId: 0,
        descriptorType: 0,
        versionNumber: 2,
        colorModel: MODEL_BC6H,
        colorPrimaries: primaries,
        transferFunction: 1,
        flags: 0,
        texelBlockDimension: [3, 3, 0, 0],
        bytesPlane: [16, 0, 0, 0, 0, 0, 0, 0],
        samples: [
          {
            bitOffset: 0,
            bitLength: 127,
            channelType: FLOAT | (signed ? SIGNED : 0),
            samplePosition: [0, 0, 0, 0],
            // Float bit patterns; ktx-parse writes SIGNED samples' limits as int32.
            sampleLower: signed ? 0xbf800000 | 0 : 0,
            sampleUpper: signed ? 0x3f800000 | 0 : 0x3f800000,
          },
        ],
      },
    ],
    keyValue: {},
    globalData: null,
  };
  writeFileSync(out, write(c));
}

function flatten(value, prefix, out) {
  if (value !== null && typeof value === 'object') {
    for (const [k, v] of Object.entries(value)) flatten(v, prefix ? `${prefix}.${k}` : k, out);
  } else {
    out.push(`${prefix}=${value}`);
  }
  return out;
}

const [cmd, ...args] = process.argv.slice(2);
if (cmd === 'read' && args.length === 1) {
  process.stdout.write(JSON.stringify(describe(args[0])) + '\n');
} else if (cmd === 'flat' && args.length === 1) {
  process.stdout.write(flatten(describe(args[0]), '', []).join('\n') + '\n');
} else if (cmd === 'write' && args.length >= 7) {
  const [out, vk, w, h, signed, primaries, ...levels] = args;
  build(out, Number(vk), Number(w), Number(h), signed === '1', Number(primaries), levels);
} else {
  process.stderr.write('usage: ktx2.mjs read FILE | write OUT VKFORMAT W H SIGNED PRIMARIES LEVEL0.bin [...]\n');
  process.exit(2);
}
