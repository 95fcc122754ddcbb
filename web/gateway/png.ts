// Enough PNG (8-bit RGB or RGBA, not interlaced: what cinevol-server and Chromium write) to place a slice in a
// viewport of the size a DICOMweb client asked for, and for the end-to-end tests to read pictures.
import { deflateSync, inflateSync } from "node:zlib";

export interface Pixels {
  width: number;
  height: number;
  channels: number;    // 3 RGB, 4 RGBA
  pixels: Uint8Array;  // rows top to bottom, `channels` bytes a pixel
}

export function decodePng(file: Buffer): Pixels {
  let at = 8;
  let width = 0, height = 0, channels = 0;
  const idat: Buffer[] = [];
  while (at < file.length) {
    const length = file.readUInt32BE(at), type = file.toString("latin1", at + 4, at + 8), data = file.subarray(at + 8, at + 8 + length);
    if (type === "IHDR") {
      width = data.readUInt32BE(0);
      height = data.readUInt32BE(4);
      if (data[8] !== 8 || data[12] !== 0 || (data[9] !== 2 && data[9] !== 6)) throw new Error("unexpected PNG format");
      channels = data[9] === 6 ? 4 : 3;
    } else if (type === "IDAT") {
      idat.push(data);
    }
    at += 12 + length;
  }
  const raw = inflateSync(Buffer.concat(idat)), stride = width * channels, pixels = new Uint8Array(stride * height);
  for (let y = 0; y < height; ++y) {
    const filter = raw[y * (stride + 1)];
    for (let x = 0; x < stride; ++x) {
      const v = raw[y * (stride + 1) + 1 + x];
      const a = x >= channels ? pixels[y * stride + x - channels] : 0;
      const b = y > 0 ? pixels[(y - 1) * stride + x] : 0;
      const c = x >= channels && y > 0 ? pixels[(y - 1) * stride + x - channels] : 0;
      const p = a + b - c, pa = Math.abs(p - a), pb = Math.abs(p - b), pc = Math.abs(p - c);
      const predictor = [0, a, b, (a + b) >> 1, pa <= pb && pa <= pc ? a : pb <= pc ? b : c][filter];
      pixels[y * stride + x] = (v + predictor) & 255;
    }
  }
  return { width, height, channels, pixels };
}

const CRC_TABLE = Array.from({ length: 256 }, (_, n) => {
  let c = n;
  for (let k = 0; k < 8; ++k) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
  return c >>> 0;
});

function crc32(bytes: Buffer): number {
  let c = 0xffffffff;
  for (const byte of bytes) c = CRC_TABLE[(c ^ byte) & 255] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}

function chunk(type: string, data: Buffer): Buffer {
  const typed = Buffer.concat([Buffer.from(type, "latin1"), data]);
  const length = Buffer.alloc(4), crc = Buffer.alloc(4);
  length.writeUInt32BE(data.length);
  crc.writeUInt32BE(crc32(typed));
  return Buffer.concat([length, typed, crc]);
}

/** An 8-bit RGB or RGBA PNG, every row unfiltered (the deflate does the work). */
export function encodePng(image: Pixels): Buffer {
  const header = Buffer.alloc(13);
  header.writeUInt32BE(image.width, 0);
  header.writeUInt32BE(image.height, 4);
  header[8] = 8;
  header[9] = image.channels === 4 ? 6 : 2;
  const stride = image.width * image.channels, raw = Buffer.alloc((stride + 1) * image.height);
  for (let y = 0; y < image.height; ++y) {
    raw.set(image.pixels.subarray(y * stride, (y + 1) * stride), y * (stride + 1) + 1);
  }
  return Buffer.concat([Buffer.from([0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a]), chunk("IHDR", header),
                        chunk("IDAT", deflateSync(raw)), chunk("IEND", Buffer.alloc(0))]);
}

/**
 * `image` centred in a black canvas of `width` x `height`: cropped evenly where it is larger (by a pixel or two
 * of rounding, as a fitted slice may be), bordered where it is smaller.
 */
export function centreIn(image: Pixels, width: number, height: number): Pixels {
  const n = image.channels, pixels = new Uint8Array(width * height * n);
  // An odd pixel of border goes to the right and bottom, an odd pixel cropped comes from there too.
  const dx = Math.trunc((width - image.width) / 2), dy = Math.trunc((height - image.height) / 2);
  for (let y = Math.max(0, dy); y < Math.min(height, dy + image.height); ++y) {
    const x0 = Math.max(0, dx), x1 = Math.min(width, dx + image.width);
    const from = ((y - dy) * image.width + (x0 - dx)) * n;
    pixels.set(image.pixels.subarray(from, from + (x1 - x0) * n), (y * width + x0) * n);
  }
  return { width, height, channels: n, pixels };
}
