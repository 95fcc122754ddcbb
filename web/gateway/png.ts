// Enough PNG (8-bit RGB or RGBA, not interlaced: what cinevol-server and Chromium write) to place a slice in a
// viewport of the size a DICOMweb client asked for, and for the end-to-end tests to read pictures.
import { promisify } from "node:util";
import { deflate, deflateSync, inflate, inflateSync } from "node:zlib";

export interface Pixels {
  width: number;
  height: number;
  channels: number;    // 3 RGB, 4 RGBA
  pixels: Uint8Array;  // rows top to bottom, `channels` bytes a pixel
}

/** The header's size and channels, and the compressed rows. */
function readChunks(file: Buffer): { header: Omit<Pixels, "pixels">; idat: Buffer } {
  let at = 8;
  const header = { width: 0, height: 0, channels: 0 }, idat: Buffer[] = [];
  while (at < file.length) {
    const length = file.readUInt32BE(at), type = file.toString("latin1", at + 4, at + 8), data = file.subarray(at + 8, at + 8 + length);
    if (type === "IHDR") {
      header.width = data.readUInt32BE(0);
      header.height = data.readUInt32BE(4);
      if (data[8] !== 8 || data[12] !== 0 || (data[9] !== 2 && data[9] !== 6)) throw new Error("unexpected PNG format");
      header.channels = data[9] === 6 ? 4 : 3;
    } else if (type === "IDAT") {
      idat.push(data);
    }
    at += 12 + length;
  }
  return { header, idat: Buffer.concat(idat) };
}

/** Rows [y0, y1) of `into` from `raw`, each row's filter undone (PNG's five: none, sub, up, average, Paeth). */
function unfilterRows(raw: Buffer, into: Pixels, y0: number, y1: number): void {
  const { channels, pixels } = into, stride = into.width * channels;
  for (let y = y0; y < y1; ++y) {
    const filter = raw[y * (stride + 1)], from = y * (stride + 1) + 1, row = y * stride, up = row - stride;
    for (let x = 0; x < stride; ++x) {
      const v = raw[from + x];
      const a = x >= channels ? pixels[row + x - channels] : 0, b = y > 0 ? pixels[up + x] : 0;
      let predictor = 0;
      if (filter === 1) predictor = a;
      else if (filter === 2) predictor = b;
      else if (filter === 3) predictor = (a + b) >> 1;
      else if (filter === 4) {
        const c = x >= channels && y > 0 ? pixels[up + x - channels] : 0;
        const p = a + b - c, pa = Math.abs(p - a), pb = Math.abs(p - b), pc = Math.abs(p - c);
        predictor = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
      }
      pixels[row + x] = (v + predictor) & 255;
    }
  }
}

const blank = (h: Omit<Pixels, "pixels">): Pixels => ({ ...h, pixels: new Uint8Array(h.width * h.height * h.channels) });

export function decodePng(file: Buffer): Pixels {
  const { header, idat } = readChunks(file);
  const image = blank(header);
  unfilterRows(inflateSync(idat), image, 0, header.height);
  return image;
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

/** Each row behind its filter byte, 0: none (the deflate does the work). */
function rows(image: Pixels): Buffer {
  const stride = image.width * image.channels, raw = Buffer.alloc((stride + 1) * image.height);
  for (let y = 0; y < image.height; ++y) {
    raw.set(image.pixels.subarray(y * stride, (y + 1) * stride), y * (stride + 1) + 1);
  }
  return raw;
}

/** A PNG file of compressed, filtered rows. */
export function assemble(image: Omit<Pixels, "pixels">, compressed: Buffer): Buffer {
  const header = Buffer.alloc(13);
  header.writeUInt32BE(image.width, 0);
  header.writeUInt32BE(image.height, 4);
  header[8] = 8;
  header[9] = image.channels === 4 ? 6 : 2;
  return Buffer.concat([Buffer.from([0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a]), chunk("IHDR", header),
                        chunk("IDAT", compressed), chunk("IEND", Buffer.alloc(0))]);
}

/** An 8-bit RGB or RGBA PNG. */
export function encodePng(image: Pixels): Buffer {
  return assemble(image, deflateSync(rows(image)));
}

const inflateAsync = promisify(inflate), deflateAsync = promisify(deflate);

// Rows of pixel bytes undone between turns of the event loop: about a millisecond's work.
const BYTES_A_TURN = 1 << 20;

/**
 * A PNG centred in a black canvas of `width` x `height` (centreIn), the event loop serving streams meanwhile: the
 * inflating and deflating in node's thread pool, the filters undone a few rows a turn (a 4096-pixel slice would
 * otherwise hold every stream for half a second).
 */
export async function fitPng(file: Buffer, width: number, height: number): Promise<Buffer> {
  const { header, idat } = readChunks(file);
  const raw = await inflateAsync(idat), image = blank(header);
  const step = Math.max(1, Math.floor(BYTES_A_TURN / (header.width * header.channels + 1)));
  for (let y = 0; y < header.height; y += step) {
    unfilterRows(raw, image, y, Math.min(header.height, y + step));
    await new Promise((r) => setImmediate(r));
  }
  const fitted = centreIn(image, width, height);
  return assemble(fitted, await deflateAsync(rows(fitted)));
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
