// A DICOMweb origin for rendered volumes (PS3.18 2024d+, "Rendered 3D and MPR" resources of Supplement 228, query
// parameters of 8.3.5): any DICOMweb client asks for a path-traced or MPR picture of a series of one of the server's
// PACS by URL, and gets it as PNG or JPEG, or a swivel as MP4 (docs/web.md, "Rendered volumes by URL"):
//   GET /dicom-web/{pacs}/studies/{study}/series/{series}/rendered3D?orientation=a&viewport=512,512&quality=80
//   GET /dicom-web/{pacs}/studies/{study}/series/{series}/rendered3D?swivelrange=360&animationstepsize=2
//       &animationrate=25 (Accept: video/mp4)
//   GET /dicom-web/{pacs}/studies/{study}/series/{series}/renderedmpr?renderingmethod=maximum_ip&mprslab=20
//       &viewpointposition=x,y,z&viewpointlookat=x,y,z&viewpointup=x,y,z&window=40,400,linear
//   GET /dicom-web/{pacs}/studies/{study}/series/{series}/instances/{presentation state}/rendered3D
//       (a Volume Rendering Volumetric Presentation State: the series it presents, in its scene)
//   GET /dicom-web/{pacs}/studies/{study}/series/{series}/instances/{instance}/frames/{frame}/rendered
//       ?window=40,400,linear&viewport=512,512 (Supplement 174: an image's frame, on its own plane and pixel grid,
//       sampled from the series' volume; /instances/{instance}/rendered for a single-frame image)
// The series comes through the server's LoadSeries (its limits, cache and reader cage), the picture from a session
// of the caller's own (their bearer token goes through as it came, or the one a signed URL stands for:
// signed_urls.ts), which ends with the answer.
import { create } from "@bufbuild/protobuf";
import { Code, ConnectError, createClient, type CallOptions, type Client, type Transport } from "@connectrpc/connect";
import { NamedView, SceneFrame, SceneSchema, type Scene } from "../gen/cinevol/v1/scene_pb.js";
import {
  ImageFormat, PacsService, SessionService, SlabProjection, SliceAxis, type VolumeInfo,
} from "../gen/cinevol/v1/service_pb.js";
import { fitPng } from "./png.js";
import type { RenderQueue } from "./render_queue.js";
import type { SignedUrls } from "./signed_urls.js";

/** The resource a path names, or undefined for a path that is not one. */
const PATH =
  /^\/dicom-web\/([A-Za-z0-9_.-]{1,64})\/studies\/([0-9.]{1,64})\/series\/([0-9.]{1,64})(?:\/instances\/([0-9.]{1,64}))?\/(rendered3d|renderedmpr)$/i;
/** A rendered frame (Supplement 174): an image instance, or one of its frames. */
const FRAME_PATH =
  /^\/dicom-web\/([A-Za-z0-9_.-]{1,64})\/studies\/([0-9.]{1,64})\/series\/([0-9.]{1,64})\/instances\/([0-9.]{1,64})(?:\/frames\/([0-9,]{1,64}))?\/rendered$/i;
/** The query parameter that carries a signed URL's capability (signed_urls.ts). */
export const SIGNATURE = "signature";

type Vec = [number, number, number];

export interface RenderedRequest {
  pacs: string;
  studyUid: string;
  seriesUid: string;
  presentationUid?: string;  // the target is a presentation state: its scene, its series
  kind: "rendered3d" | "renderedmpr" | "renderedframe";
  // A rendered frame's image and frame number (0: the instance itself, a single-frame image).
  frame?: { instanceUid: string; number: number };
  method: "volume_rendered" | "maximum_ip" | "minimum_ip" | "average_ip";
  orientation?: "a" | "p" | "r" | "l" | "h" | "f";
  position?: Vec;
  lookAt?: Vec;
  up?: Vec;
  slabMm: number;
  window?: { center: number; width: number };
  viewport: { width: number; height: number };
  viewportGiven: boolean;  // an MPR without one is at the volume's resolution, with one exactly that size
  quality: number;  // 1 to 100
  // A swivel animation (video/mp4): the camera turned `degrees` about its up axis through its target, `stepDegrees` a
  // frame, `rate` frames a second: SessionService.RenderMovie's orbit (docs/movies.md).
  swivel?: { degrees: number; stepDegrees: number; rate: number };
  accept: "image/jpeg" | "image/png" | "application/dicom+json" | "video/mp4";
}

/** A refusal as the standard's status codes say it: 400 a bad value, 406 a media type not offered. */
export class Refusal extends Error {
  constructor(readonly status: number, message: string) {
    super(message);
  }
}

const MAX_SIDE = 4096;

function numbers(query: URLSearchParams, name: string, count: number): number[] | undefined {
  const text = query.get(name);
  if (text === null) return undefined;
  const values = text.split(",").map((v) => Number(v.trim()));
  if (values.length !== count || values.some((v) => !Number.isFinite(v) || Math.abs(v) > 1e7)) {
    throw new Refusal(400, `${name}: '${text}' is not ${count} numbers`);
  }
  return values;
}

function vec(query: URLSearchParams, name: string): Vec | undefined {
  return numbers(query, name, 3) as Vec | undefined;
}

/**
 * The media type answered: the `accept` parameter, else the Accept header's first one offered. A swivel is a video
 * (video/mp4); anything else an image (JPEG by default).
 */
function mediaType(query: URLSearchParams, acceptHeader: string | undefined): RenderedRequest["accept"] {
  if (query.get("renderedvolumetricmetadata") === "yes") return "application/dicom+json";
  const swivel = query.has("swivelrange");
  const asked = (query.get("accept") ?? acceptHeader ?? (swivel ? "video/mp4" : "image/jpeg")).split(",")
    .map((t) => t.split(";")[0].trim());
  for (const type of asked) {
    if (swivel && ["video/mp4", "video/*", "*/*"].includes(type)) return "video/mp4";
    if (!swivel && (type === "image/jpeg" || type === "image/png")) return type;
    if (!swivel && (type === "image/*" || type === "*/*")) return "image/jpeg";
  }
  if (!swivel && asked.some((t) => t.startsWith("video/"))) {
    throw new Refusal(400, "swivelrange: a video of a rendered volume is a swivel; give its range in degrees");
  }
  throw new Refusal(406, swivel ? `none of '${asked.join(", ")}' is offered for a swivel animation: video/mp4`
                                : `none of '${asked.join(", ")}' is offered: image/jpeg or image/png`);
}

const MAX_SWIVEL_FRAMES = 3600;  // RenderMovie's most

/** swivelrange (degrees), animationstepsize (degrees a frame, default 2) and animationrate (frames a second, 25). */
function swivelOf(query: URLSearchParams): RenderedRequest["swivel"] {
  if (!query.has("swivelrange")) {
    const stray = ["animationstepsize", "animationrate"].find((name) => query.has(name));
    if (stray) throw new Refusal(400, `${stray}: says how a swivel animates; give swivelrange too`);
    return undefined;
  }
  const degrees = Number(query.get("swivelrange"));
  const stepDegrees = Number(query.get("animationstepsize") ?? "2");
  const rate = Number(query.get("animationrate") ?? "25");
  if (!Number.isFinite(degrees) || degrees === 0 || Math.abs(degrees) > 3600) {
    throw new Refusal(400, "swivelrange: degrees, non-zero, at most 3600 either way");
  }
  if (!(stepDegrees > 0 && stepDegrees <= 360)) throw new Refusal(400, "animationstepsize: degrees a frame, (0, 360]");
  if (!Number.isInteger(rate) || rate < 1 || rate > 60) throw new Refusal(400, "animationrate: frames a second, 1 to 60");
  const frames = Math.ceil(Math.abs(degrees) / stepDegrees);
  if (frames > MAX_SWIVEL_FRAMES) {
    throw new Refusal(400, `animationstepsize: ${degrees} degrees at ${stepDegrees} a frame is ${frames} frames; ` +
                           `at most ${MAX_SWIVEL_FRAMES}`);
  }
  return { degrees, stepDegrees, rate };
}

/** An MPR or a frame is PNG (lossless, as reading needs): PNG or a wildcard among the types asked gets it, else 406. */
function mprMediaType(query: URLSearchParams, acceptHeader: string | undefined,
                      chosen: RenderedRequest["accept"]): RenderedRequest["accept"] {
  if (chosen !== "image/jpeg") return chosen;
  const asked = (query.get("accept") ?? acceptHeader ?? "*/*").split(",").map((t) => t.split(";")[0].trim());
  if (asked.some((t) => ["image/png", "image/*", "*/*"].includes(t))) return "image/png";
  throw new Refusal(406, `none of '${asked.join(", ")}' is offered for an MPR or a frame: image/png (lossless)`);
}

/** The request a URL makes, or a Refusal; undefined where the path is not a rendered resource. */
export function readRendered(path: string, search: string, acceptHeader?: string): RenderedRequest | undefined {
  const frameMatch = FRAME_PATH.exec(path);
  if (frameMatch) return readFrame(frameMatch, new URLSearchParams(search), acceptHeader);
  const match = PATH.exec(path);
  if (!match) return misshapen(path);
  const query = new URLSearchParams(search);
  const kind = match[5].toLowerCase() as RenderedRequest["kind"];
  const presentationUid = match[4];
  if (presentationUid !== undefined) {
    if (kind !== "rendered3d") throw new Refusal(400, "an instance renders as rendered3D (a presentation state)");
    // PS3.18 8.3.5: these say what a presentation state already says.
    const says = ["renderingmethod", "swivelrange", "animationstepsize", "animationrate", "renderedvolumetricmetadata"]
      .find((name) => query.has(name));
    if (says) throw new Refusal(400, `${says}: a presentation state's rendering says it`);
  }
  const method = (query.get("renderingmethod") ?? (kind === "rendered3d" ? "volume_rendered" : "maximum_ip"));
  if (!["volume_rendered", "maximum_ip", "minimum_ip", "average_ip"].includes(method)) {
    throw new Refusal(400, `renderingmethod: '${method}' is not volume_rendered, maximum_ip, minimum_ip or average_ip`);
  }
  if ((kind === "rendered3d") !== (method === "volume_rendered")) {
    throw new Refusal(400, `renderingmethod: ${method} is ${kind === "rendered3d" ? "an MPR's (renderedmpr)" :
                                                            "a 3D rendering's (rendered3D)"}`);
  }
  const orientation = query.get("orientation") ?? undefined;
  if (orientation !== undefined && !["a", "p", "r", "l", "h", "f"].includes(orientation)) {
    throw new Refusal(400, `orientation: '${orientation}' is not a, p, r, l, h or f`);
  }
  const slab = Number(query.get("mprslab") ?? "0");
  if (!Number.isFinite(slab) || slab < 0 || slab > 1e4) throw new Refusal(400, "mprslab: a thickness in mm, 0 to 1e4");
  const request: RenderedRequest = {
    pacs: match[1], studyUid: match[2], seriesUid: match[3], presentationUid, kind,
    method: method as RenderedRequest["method"],
    orientation: orientation as RenderedRequest["orientation"], position: vec(query, "viewpointposition"),
    lookAt: vec(query, "viewpointlookat"), up: vec(query, "viewpointup"), slabMm: slab, ...pictureOf(query),
    swivel: swivelOf(query),
    accept: kind === "renderedmpr" ? mprMediaType(query, acceptHeader, mediaType(query, acceptHeader))
                                   : mediaType(query, acceptHeader),
  };
  if ((request.position === undefined) !== (request.lookAt === undefined)) {
    throw new Refusal(400, "viewpointposition and viewpointlookat: give both or neither");
  }
  if (kind === "renderedmpr" && request.swivel) throw new Refusal(400, "swivelrange: an MPR does not swivel");
  if (request.swivel && request.viewport.width % 2 + request.viewport.height % 2 > 0) {
    throw new Refusal(400, "viewport: a swivel's video needs each side even (4:2:0 chroma)");
  }
  if (kind === "renderedmpr" && request.position === undefined) {
    throw new Refusal(400, "renderedmpr: viewpointposition and viewpointlookat say the plane (through the look-at " +
                           "point, across the view)");
  }
  return request;
}

/** What says a view of a volume, not a frame's (its plane is its own). */
const VIEW_PARAMETERS = ["renderingmethod", "orientation", "viewpointposition", "viewpointlookat", "viewpointup",
  "mprslab", "swivelrange", "animationstepsize", "animationrate", "renderedvolumetricmetadata"];

/** What any rendered picture's query says: its window, size and quality (PS3.18 8.3.5.1). */
function pictureOf(query: URLSearchParams): Pick<RenderedRequest, "window" | "viewport" | "viewportGiven" | "quality"> {
  const asked = numbers(query, "viewport", 2), [vw, vh] = asked ?? [512, 512];
  if (![vw, vh].every((n) => Number.isInteger(n) && n >= 1 && n <= MAX_SIDE)) {
    throw new Refusal(400, `viewport: each side a whole number in [1, ${MAX_SIDE}]`);
  }
  const quality = Number(query.get("quality") ?? "75");
  if (!Number.isInteger(quality) || quality < 1 || quality > 100) throw new Refusal(400, "quality: 1 to 100");
  let window: RenderedRequest["window"];
  const windowText = query.get("window");
  if (windowText !== null) {
    const [center, width, shape] = windowText.split(",");
    if (!Number.isFinite(Number(center)) || !(Number(width) > 0) || (shape ?? "").toLowerCase() !== "linear") {
      throw new Refusal(400, `window: '${windowText}' is not center,width,linear (cinevol applies linear windows)`);
    }
    window = { center: Number(center), width: Number(width) };
  }
  return { window, viewport: { width: vw, height: vh }, viewportGiven: asked !== undefined, quality };
}

/** A rendered frame's request: one frame (a list of several needs a multi-frame media type: 406), its window and
 * viewport (the frame's field fitted within it), as PNG like an MPR. */
function readFrame(match: RegExpExecArray, query: URLSearchParams, acceptHeader: string | undefined): RenderedRequest {
  const stray = VIEW_PARAMETERS.find((name) => query.has(name));
  if (stray) throw new Refusal(400, `${stray}: says a view of a volume; a rendered frame lies on its own plane`);
  const list = match[5];  // none: the instance itself (frame 0, a single-frame image's only one)
  const numbers = list === undefined ? [0] : list.split(",").map(Number);
  if (list !== undefined && numbers.some((n) => !Number.isSafeInteger(n) || n < 1)) {
    throw new Refusal(400, `frames: '${list}' is not a list of frame numbers from 1`);
  }
  if (numbers.length > 1) {
    throw new Refusal(406, `frames: ${numbers.length} frames answer only in a multi-frame media type, which cinevol ` +
                           "does not offer: ask for one frame a request");
  }
  return {
    pacs: match[1], studyUid: match[2], seriesUid: match[3], kind: "renderedframe",
    frame: { instanceUid: match[4], number: numbers[0] }, method: "maximum_ip", slabMm: 0, ...pictureOf(query),
    accept: mprMediaType(query, acceptHeader, mediaType(query, acceptHeader)),
  };
}

/** Why a path under /dicom-web/ names no rendered resource (400 for a segment that is not a name, else 404). */
function misshapen(path: string): undefined {
  if (!/^\/dicom-web(\/|$)/i.test(path)) return undefined;
  const quoted = (text: string) => `'${text.length > 80 ? `${text.slice(0, 80)}...` : text}'`;
  // A rendered resource's shape whatever its segments hold (a URL where the PACS name goes, a UID that is not
  // one), found by searching, not by a pattern that could backtrack over a long path.
  const studies = path.indexOf("/studies/", "/dicom-web/".length);
  const shaped = studies > 0 && path.indexOf("/series/", studies) > 0 && /\/rendered(?:3d|mpr)?$/i.test(path);
  const pacs = path.slice("/dicom-web/".length, studies);
  if (shaped && !/^[A-Za-z0-9_.-]{1,64}$/.test(pacs)) {
    throw new Refusal(400, `pacs: ${quoted(pacs)} is not a PACS name: one of the server's --pacs names ` +
                           "(letters, digits, '_', '.', '-'), never an address");
  }
  if (shaped) {
    throw new Refusal(400, "studies, series, instances: each UID is digits and dots, 64 at most; frames: a number");
  }
  throw new Refusal(404, `${quoted(path)} is not a rendered resource: ` +
                         "/dicom-web/{pacs}/studies/{study}/series/{series}[/instances/{instance}]/rendered3D or " +
                         "renderedmpr, .../instances/{instance}[/frames/{frame}]/rendered " +
                         "(or POST /dicom-web/signed-url)");
}

const VIEWS: Record<string, NamedView> = {
  a: NamedView.ANTERIOR, p: NamedView.POSTERIOR, r: NamedView.RIGHT, l: NamedView.LEFT, h: NamedView.SUPERIOR,
  f: NamedView.INFERIOR,
};

// Samples per pixel from the quality: 1 at 1, 2^10 at 100, 64 at 60.
const sppOf = (quality: number) => Math.max(1, Math.round(2 ** (quality / 10)));

const sub = (a: Vec, b: Vec): Vec => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const dot = (a: Vec, b: Vec) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a: Vec, b: Vec): Vec => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const scale = (a: Vec, s: number): Vec => [a[0] * s, a[1] * s, a[2] * s];
const xyz = (v: Vec) => ({ x: v[0], y: v[1], z: v[2] });

/** A 3D view's scene: its camera in the patient (viewpoint parameters) or a named view; the volume's default preset. */
function sceneOf(r: RenderedRequest): Scene | undefined {
  if (r.kind !== "rendered3d") return undefined;
  if (r.position && r.lookAt) {
    return create(SceneSchema, { frame: SceneFrame.PATIENT_LPS,
                                 camera: { eye: xyz(r.position), target: xyz(r.lookAt), up: r.up && xyz(r.up) } });
  }
  return r.orientation ? create(SceneSchema, { camera: { view: VIEWS[r.orientation] } }) : undefined;
}

/** Where a volume lies in the patient, as VolumeInfo says it. */
export interface Placement {
  direction: number[];  // row-major: column c is index axis c's direction in the patient
  originMm: Vec;        // voxel (0, 0, 0)'s centre, LPS mm
  spacingMm: Vec;
  dims: Vec;
}

export function placementOf(v: VolumeInfo): Placement {
  const triple = (p: { x: number; y: number; z: number } | undefined): Vec => [p?.x ?? 0, p?.y ?? 0, p?.z ?? 0];
  return { direction: v.direction.length === 9 ? v.direction : [1, 0, 0, 0, 1, 0, 0, 0, 1],
           originMm: triple(v.originMm), spacingMm: triple(v.spacingMm), dims: triple(v.dims) };
}

/** An MPR's plane and sampling, as RenderSlice takes them. */
export interface MprPlan {
  point: Vec;        // the look-at point, on the plane (LPS mm)
  normal: Vec;       // unit, from the viewpoint to the look-at point
  row: Vec;          // unit, across the normal: the image's rows run along it (the view's right)
  pixelMm: number;   // 0: the server's own (the volume's smallest spacing, as `cinevol slice`)
  slabMm: number;    // as asked, or as far as the volume reaches from the plane on its far side
  slabNote?: string; // what became of a slab thicker than the volume
}

// The slice's pixels over `span` mm at `pixelMm`, the outermost centres on its ends (server/reading/slice.cpp).
const pixelsOver = (span: number, pixelMm: number) => Math.round(span / pixelMm) + 1;

/**
 * The plane of an MPR through the look-at point across the view, the row along the view's right (`viewpointup`,
 * default the patient's head, up the image), and the pixel size that fits the whole cross-section of the volume
 * into the viewport with square pixels (the server's own where it already fits exactly, as `cinevol slice` makes
 * it). A slab reaching past the volume on both sides projects all of it: it is cut to what the volume reaches
 * (a voxel more), which samples the same voxels, and the note says so.
 */
export function planMpr(r: RenderedRequest, volume: Placement): MprPlan {
  const towards = sub(r.lookAt!, r.position!), length = Math.hypot(...towards);
  if (!(length > 1e-6)) throw new Refusal(400, "viewpointposition and viewpointlookat are one point: no view");
  const normal = scale(towards, 1 / length);
  const across = cross(normal, r.up ?? [0, 0, 1]), acrossLength = Math.hypot(...across);
  if (!(acrossLength > 1e-3 * Math.hypot(...(r.up ?? [0, 0, 1])))) {
    throw new Refusal(400, "viewpointup lies along the view (from viewpointposition to viewpointlookat)");
  }
  const row = scale(across, 1 / acrossLength), column = cross(normal, row);
  const corners = cornerCentres(volume);
  const span = (axis: Vec) => {
    const t = corners.map((c) => dot(sub(c, r.lookAt!), axis));
    return { lo: Math.min(...t), hi: Math.max(...t) };
  };
  const plan: MprPlan = { point: r.lookAt!, normal, row, pixelMm: 0, slabMm: r.slabMm };
  const depth = span(normal), reach = Math.max(depth.hi, -depth.lo) + Math.max(...volume.spacingMm);
  if (r.slabMm / 2 > reach) {
    plan.slabMm = 2 * reach;
    plan.slabNote = `mprslab: ${r.slabMm} mm reaches past the volume, which lies within ` +
                    `${Math.max(depth.hi, -depth.lo).toFixed(1)} mm of the plane: the slab projects all of it`;
  }
  if (!r.viewportGiven) return plan;
  const wide = span(row), tall = span(column), { width, height } = r.viewport;
  const own = Math.min(...volume.spacingMm);
  if (own > 0 && pixelsOver(wide.hi - wide.lo, own) === width && pixelsOver(tall.hi - tall.lo, own) === height) {
    return plan;
  }
  const fitted = Math.max((wide.hi - wide.lo) / Math.max(width - 1, 1), (tall.hi - tall.lo) / Math.max(height - 1, 1));
  plan.pixelMm = Math.min(1e4, Math.max(1e-3, fitted));
  return plan;
}

const add = (a: Vec, b: Vec): Vec => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
/** D v: a vector of the volume's index axes (mm) in the patient. */
const rotate = (p: Placement, v: Vec): Vec =>
  [0, 1, 2].map((row) => dot([p.direction[3 * row], p.direction[3 * row + 1], p.direction[3 * row + 2]], v)) as Vec;

/** The patient positions of the volume's eight outermost voxel centres. */
function cornerCentres(v: Placement): Vec[] {
  const corners: Vec[] = [];
  for (let i = 0; i < 8; ++i) {
    const mm = [0, 1, 2].map((a) => ((i >> a) & 1 ? v.dims[a] - 1 : 0) * v.spacingMm[a]) as Vec;
    corners.push(add(v.originMm, rotate(v, mm)));
  }
  return corners;
}

/** The standard's status for a failure the server reported. */
export function statusOf(e: unknown): { status: number; message: string } {
  const error = ConnectError.from(e);
  const status: Partial<Record<Code, number>> = {
    [Code.InvalidArgument]: 400, [Code.NotFound]: 404, [Code.Unauthenticated]: 401, [Code.PermissionDenied]: 403,
    [Code.ResourceExhausted]: 429, [Code.FailedPrecondition]: 400, [Code.Unavailable]: 503,
    [Code.DeadlineExceeded]: 504,
  };
  return { status: status[error.code] ?? 500, message: error.rawMessage };
}

export interface Rendered {
  type: string;
  body: Buffer;
  warning?: string;  // said in a Warning header (299), as PS3.18 does for a parameter the answer departs from
}

/** Renders `r` with the server behind `transport`, as the caller whose Authorization header is `authorization`. */
export async function render(transport: Transport, r: RenderedRequest, authorization: string | undefined,
                             signal: AbortSignal): Promise<Rendered> {
  const headers = new Headers();
  if (authorization) headers.set("authorization", authorization);
  const call: CallOptions = { headers, signal, timeoutMs: 300_000 };
  const pacs = createClient(PacsService, transport), sessions = createClient(SessionService, transport);
  let series = { studyUid: r.studyUid, seriesUid: r.seriesUid }, scene = sceneOf(r);
  if (r.presentationUid) {  // its series in its scene, a camera asked for over its own
    const presented = await pacs.loadPresentation({ pacs: r.pacs, studyUid: r.studyUid, seriesUid: r.seriesUid,
                                                    sopInstanceUid: r.presentationUid }, call);
    series = { studyUid: presented.studyUid, seriesUid: presented.seriesUid };
    scene = presented.scene;
    if (scene && scene.camera && (r.position || r.orientation)) scene.camera = sceneOf(r)?.camera ?? scene.camera;
  }
  let volume: VolumeInfo | undefined;
  for await (const update of pacs.loadSeries({ pacs: r.pacs, ...series }, call)) {
    if (update.update.case === "volume") volume = update.update.value;
  }
  if (!volume) throw new Refusal(502, "the server loaded the series but did not say which volume it made");
  if (r.frame) return frame(pacs, r, call);
  // An MPR's plane is checked before a session is made for it.
  const plan = r.kind === "renderedmpr" ? planMpr(r, placementOf(volume)) : undefined;
  const volumeId = volume.id;
  const created = await sessions.createSession({
    volumeId, viewport: { width: r.viewport.width, height: r.viewport.height },
    initial: scene ? { case: "scene", value: scene } : { case: undefined },
  }, call);
  try {
    if (r.accept === "application/dicom+json") return metadata(r, created.scene, placementOf(volume));
    if (r.swivel) return { type: "video/mp4", body: await swivel(sessions, created.sessionId, r, call) };
    if (r.kind === "rendered3d") {
      const still = await sessions.snapshot({
        sessionId: created.sessionId, spp: sppOf(r.quality),
        format: r.accept === "image/png" ? ImageFormat.PNG : ImageFormat.JPEG,
      }, call);
      return { type: r.accept, body: Buffer.from(still.image) };
    }
    const slice = await sessions.renderSlice({
      sessionId: created.sessionId, axis: SliceAxis.OBLIQUE, point: xyz(plan!.point), normal: xyz(plan!.normal),
      row: xyz(plan!.row), slabMm: plan!.slabMm, pixelMm: plan!.pixelMm,
      projection: { maximum_ip: SlabProjection.MAXIMUM, minimum_ip: SlabProjection.MINIMUM,
                    average_ip: SlabProjection.MEAN, volume_rendered: SlabProjection.MAXIMUM }[r.method],
      ...(r.window ? { window: r.window.width, level: r.window.center } : {}),
    }, call);
    const { width, height } = r.viewport;
    const fits = !r.viewportGiven || (slice.width === width && slice.height === height);
    return { type: "image/png", warning: plan!.slabNote,
             body: fits ? Buffer.from(slice.png) : await fitPng(Buffer.from(slice.png), width, height) };
  } finally {
    await sessions.closeSession({ sessionId: created.sessionId }, call).catch(() => {});
  }
}

/** A rendered frame: its plane and grid sampled from the series' volume, which the caller now holds (RenderFrame). */
async function frame(pacs: Client<typeof PacsService>, r: RenderedRequest, call: CallOptions): Promise<Rendered> {
  const { width, height } = r.viewport;
  const slice = await pacs.renderFrame({
    pacs: r.pacs, studyUid: r.studyUid, seriesUid: r.seriesUid, sopInstanceUid: r.frame!.instanceUid,
    frame: r.frame!.number, ...(r.window ? { window: r.window.width, level: r.window.center } : {}),
    ...(r.viewportGiven ? { viewport: { width, height } } : {}),
  }, call);
  const fits = !r.viewportGiven || (slice.width === width && slice.height === height);
  return { type: "image/png", body: fits ? Buffer.from(slice.png) : await fitPng(Buffer.from(slice.png), width, height) };
}

/** A swivel animation: the session's view turned as the request says, a movie the server makes (RenderMovie). */
async function swivel(sessions: Client<typeof SessionService>, sessionId: string, r: RenderedRequest,
                      call: CallOptions): Promise<Buffer> {
  const { degrees, stepDegrees, rate } = r.swivel!;
  const frames = Math.ceil(Math.abs(degrees) / stepDegrees);
  for await (const update of sessions.renderMovie({
    sessionId, path: { case: "orbitDegrees", value: degrees }, seconds: frames / rate, fps: rate, spp: sppOf(r.quality),
  }, call)) {
    if (update.update.case === "movie") return Buffer.from(update.update.value.mp4);
  }
  throw new Refusal(502, "the server ended the swivel without its video");
}

/** The parameters used, as DICOM JSON (PS3.18 Annex K): the view the session resolved (in the patient, LPS mm, as
 * the viewpoint parameters are), the method and size. */
function metadata(r: RenderedRequest, scene: Scene | undefined, volume: Placement): Rendered {
  const camera = scene?.camera, inPatient = scene?.frame === SceneFrame.PATIENT_LPS;
  const triple = (v: { x: number; y: number; z: number }): Vec => [v.x, v.y, v.z];
  // The volume-centred frame's point v lies at origin + D (v + (dims - 1) spacing / 2) in the patient.
  const point = (v: Vec) => add(volume.originMm, rotate(volume, v.map((c, a) =>
    c + ((volume.dims[a] - 1) * volume.spacingMm[a]) / 2) as Vec));
  const fd = (v: { x: number; y: number; z: number } | undefined, kind: "point" | "direction") => ({
    vr: "FD", Value: !v ? [] : inPatient ? triple(v) : kind === "point" ? point(triple(v)) : rotate(volume, triple(v)),
  });
  const body = {
    "00701602": { vr: "CS", Value: ["PERSPECTIVE"] },
    "00701603": fd(camera?.eye, "point"), "00701604": fd(camera?.target, "point"),
    "00701605": fd(camera?.up, "direction"),
    "0070120D": { vr: "CS", Value: [r.method.toUpperCase()] },
    // An MPR without a viewport is at the volume's resolution: its size is the plane's, not said here.
    ...(r.kind === "rendered3d" || r.viewportGiven
      ? { "00280010": { vr: "US", Value: [r.viewport.height] }, "00280011": { vr: "US", Value: [r.viewport.width] } }
      : {}),
  };
  return { type: "application/dicom+json", body: Buffer.from(JSON.stringify([body])) };
}

/** What answer() needs of a node request and response (HTTP/1.1 or HTTP/2 alike). */
export interface Request {
  url?: string;
  method?: string;
  headers: Record<string, string | string[] | undefined>;
  on(event: "close", listener: () => void): unknown;
}
export interface Response {
  writeHead(status: number, headers: Record<string, string | number>): unknown;
  end(body: Buffer | string): unknown;
  writableEnded: boolean;
}

/** The resource a signed URL is good for: the path's PACS, study, series, instance and kind (its query may vary). */
export const scopeOf = (r: RenderedRequest) => {
  const series = `/dicom-web/${r.pacs}/studies/${r.studyUid}/series/${r.seriesUid}`;
  if (r.frame) {
    return `${series}/instances/${r.frame.instanceUid}${r.frame.number ? `/frames/${r.frame.number}` : ""}/rendered`;
  }
  return `${series}${r.presentationUid ? `/instances/${r.presentationUid}` : ""}/` +
         (r.kind === "rendered3d" ? "rendered3D" : "renderedmpr");
};

/** A request's path and query (the query without its "?"; a "?" inside it stays). */
export function splitUrl(url: string): [string, string] {
  const at = url.indexOf("?");
  return at < 0 ? [url, ""] : [url.slice(0, at), url.slice(at + 1)];
}

/**
 * Answers a rendered-volume request with its picture or the standard's status; false where `req` names none. A
 * request carrying a signed URL's capability (`signature`) is served as the caller who had it made, where `signed`
 * holds it for this resource.
 */
export function answerRendered(transport: Transport, req: Request, res: Response, queue: RenderQueue,
                               signed?: SignedUrls): boolean {
  const [path, search] = splitUrl(req.url ?? "/");
  const header = (name: string) => { const v = req.headers[name]; return Array.isArray(v) ? v.join(",") : v; };
  let request: RenderedRequest | undefined, authorization = header("authorization");
  try {
    request = readRendered(path, search, header("accept"));
    if (!request) return false;
    if (req.method !== "GET") throw new Refusal(405, "a rendered resource answers GET");
    const capability = new URLSearchParams(search).get(SIGNATURE);
    if (capability !== null) {
      if (authorization) throw new Refusal(400, "give a signed URL or an Authorization header, not both");
      if (!signed) throw new Refusal(401, "this gateway makes no signed URLs");
      authorization = signed.redeem(capability, scopeOf(request));
    }
  } catch (e) {
    if (!(e instanceof Refusal)) throw e;
    reply(res, e.status, e.message);
    return true;
  }
  const gone = new AbortController();
  req.on("close", () => gone.abort());
  queue.run(authorization, gone.signal, () => render(transport, request, authorization, gone.signal)).then(
    (picture) => {
      if (res.writableEnded) return;
      res.writeHead(200, { "content-type": picture.type, "content-length": picture.body.length,
                           "cache-control": "no-store", "x-content-type-options": "nosniff",
                           ...(picture.warning ? { warning: `299 cinevol-web ${JSON.stringify(picture.warning)}` } : {}) });
      res.end(picture.body);
    },
    (e: unknown) => {
      const { status, message } = e instanceof Refusal ? { status: e.status, message: e.message } : statusOf(e);
      if (!res.writableEnded) reply(res, status, message);
    });
  return true;
}

export function reply(res: Response, status: number, message: string): void {
  res.writeHead(status, { "content-type": "text/plain; charset=utf-8", "cache-control": "no-store",
                          "x-content-type-options": "nosniff" });
  res.end(`${message}\n`);
}
