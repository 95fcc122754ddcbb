// The page once signed in: the volumes and PACS, a session on the 3D view,
// the panels that edit it, the stats overlay and the keyboard; or a session
// shared with this page (#grant=), watched, and driven while this page
// presents. Every edit is an event to the server; every control shows the
// state the server answers.
import { create, toJsonString } from "@bufbuild/protobuf";
import { Code, type ConnectError } from "@connectrpc/connect";
import {
  AreaLightSchema, CameraSchema, ClippingSchema, ClipPlaneSchema, CropBoxSchema, LabelsSchema, LabelStyleSchema,
  LightSchema, MeasurementSchema, NamedView, SceneFrame, SceneSchema, TransferFunctionSchema, Vec3Schema,
  type Light, type Scene,
} from "../gen/cinevol/v1/scene_pb.js";
import {
  FinalFormat, LightListSchema, MeasurementListSchema, PointerSchema, SliceAxis, StreamSettingsSchema, ViewportSchema,
  type Frame, type SessionState, type VolumeInfo,
} from "../gen/cinevol/v1/service_pb.js";
import type { Api } from "./api.js";
import {
  DEGREES_PER_PIXEL, lightDirection, namedView, orbit, pan, setLightDirection, zoom, type ViewCamera, type ViewName,
} from "./camera.js";
import { sessionQuery } from "./address.js";
import type { FrameMeta } from "./frame_messages.js";
import { cropFromFractions, fromPatient, patientBox, toPatient } from "./geometry.js";
import { identityCorners } from "./identity.js";
import { markerAxes } from "./orientation.js";
import { measurementText, projectToView } from "./measure.js";
import { messageToShow, type Messages } from "./messages.js";
import { PacsPanel } from "./pacs_panel.js";
import { drawPointers, echoedName, othersPointers, Throttle, type Fraction, type FrameRect, type Pointer } from "./pointers.js";
import { Reading } from "./reading.js";
import { LiveSession, now, type EventKind } from "./session.js";
import { ownName, presence, SharePanel } from "./share.js";
import { MotionToPhoton, percentile, Rate } from "./stats.js";
import { TransferEditor } from "./tf_editor.js";
import { applyWindowLevel } from "./transfer.js";
import { add, len, norm, scale, sub, v3, type V3 } from "./vec.js";
import { View } from "./view.js";
import { plainWords, shareWords } from "./words.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;
const KEY_VIEWS: Record<string, ViewName> = {
  a: "ANTERIOR", p: "POSTERIOR", l: "LEFT", r: "RIGHT", s: "SUPERIOR", i: "INFERIOR",
};
const AXES = ["x", "y", "z"] as const;
/** The slice planes on the 3D view in 3D Slicer's colours: axial red, coronal green, sagittal yellow. */
const PLANE_COLOURS: Partial<Record<SliceAxis, string>> = {
  [SliceAxis.AXIAL]: "#e44", [SliceAxis.CORONAL]: "#4c4", [SliceAxis.SAGITTAL]: "#ec4",
};
const PASSING_MS = 6000;
const INPUT_RECENT_MS = 100;  // an input event this recent is what an event answers
const vec3 = (v: V3) => create(Vec3Schema, { x: v.x, y: v.y, z: v.z });
const AXIS_NAMES = { x: "Right–left", y: "Anterior–posterior", z: "Inferior–superior" };
/** The controls that send events: disabled while this page does not drive (a share's viewer). */
const DRIVING = "#preset, #view-controls button, #clipping input, #labels-panel input, #light input, #lossless, #quality";

export class App {
  readonly view = new View($("view"));
  private readonly editor = new TransferEditor($("tf-editor"), $("tf-note"));
  private readonly reading: Reading;
  private readonly share: SharePanel;
  private readonly latency = new MotionToPhoton();
  private readonly painted = new Rate();
  private readonly received = new Rate();
  private readonly decodeMs: number[] = [];  // the worker's decode and draw of each frame painted, newest last
  private session?: LiveSession;
  private volume?: VolumeInfo;
  private state?: SessionState;
  private camera?: ViewCamera;
  private home?: ViewCamera;
  private lastFrame?: Frame;
  private lastPainted?: FrameMeta;
  private replaced = 0;
  private framesPainted = 0;
  private readonly frameIds: number[] = [];  // the frames painted, newest last (tests compare a watcher's with the owner's)
  private readonly pointer = new Throttle<Fraction | null>((at) => this.sendPointer(at));
  private pointerSent?: Fraction;       // where this page's pointer went last (undefined: hidden)
  private pointerRefused = false;       // this share does not allow a pointer (until the presenter changes)
  private echoedName?: string;          // one's own name, from the server's echo of one's pointer
  private drawnPointers: Pointer[] = [];
  private driving = true;
  private readonly said: Messages = { error: "", banner: "", waiting: "Connecting to the server…" };
  private readonly messages: string[] = [];  // what the banner and the error line said, newest last
  private painted1st!: () => void;
  /** The server refused the page's token (or a user's share came without one): main.ts asks for one. */
  onTokenRefused: () => void = () => {};
  /** Settles with the first frame painted, or with a failure shown. */
  readonly firstPaint = new Promise<void>((resolve) => { this.painted1st = resolve; });

  constructor(private readonly api: Api) {
    this.reading = new Reading(api, () => this.session?.id, (text) => this.showError(text));
    this.reading.onOverlayChanged = () => this.drawOverlay();
    this.reading.onNotice = (text) => this.setBanner(text, true);
    this.reading.onMeasurementsEdited = (list) => this.post({ case: "measurements", value: create(MeasurementListSchema, {
      measurements: list.map((m) => create(MeasurementSchema, { points: m.points.map(vec3) })) }) });
    this.share = new SharePanel(api, () => this.session?.id, (text) => this.showError(text), () => this.pinCamera());
    this.view.onPainted = (meta, at, decodeMs, replaced) => this.onPainted(meta, at, decodeMs, replaced);
    this.view.onError = (text) => this.showError(text);
    this.view.listen({
      orbit: (dx, dy) => this.moveCamera((c) => orbit(c, dx * DEGREES_PER_PIXEL, dy * DEGREES_PER_PIXEL)),
      pan: (dx, dy, h) => this.moveCamera((c) => pan(c, dx, dy, h)),
      zoom: (f) => this.moveCamera((c) => zoom(c, f)),
      windowLevel: (dx, dy) => this.windowLevel(dx, dy),
      turnLight: (dx, dy) => this.turnLight(dx, dy),
      pick: (fx, fy, frame) => {
        // Not by a share: Pick, as RenderSlice, names the session, which only its owner may.
        if (!this.session?.grant) void this.reading.pickOnView(fx * frame.width, fy * frame.height, frame);
      },
      point: (at) => this.point(at),
    });
    this.view.followSize((size) => this.post({ case: "resize", value: create(ViewportSchema, size) }));
    this.editor.onEdit = (tf) => this.post({ case: "transferFunction", value: tf });
    this.wirePanels();
    this.showMessage();
    setInterval(() => this.drawStats(), 250);
  }

  /** Fills the lists, then opens what the address names. Throws (in words) when the token is refused. */
  async boot(address: { volume?: string; preset?: string; session?: string; grant?: string }): Promise<void> {
    if (address.grant) return this.watchShared(address.grant);
    const status = await this.api.server.getStatus({});
    const presets = $<HTMLSelectElement>("preset");
    presets.replaceChildren(new Option("(choose a preset)", ""), ...status.presets.map((p) => new Option(p, p)));
    const volumes = await this.api.volumes.listVolumes({});
    $<HTMLSelectElement>("volumes").replaceChildren(...volumes.volumes.map((v) => new Option(v.id, v.id)));
    void new PacsPanel(this.api, (volume) => void this.open(volume.id), (t) => this.setBanner(t),
                       (t) => this.showError(t)).start();
    // An address that names no volume opens the server's first, as the desktop viewer does: never a blank view.
    const volumeId = address.volume ?? volumes.volumes[0]?.id;
    if (address.session) await this.join(address.session);
    else if (volumeId) await this.open(volumeId, address.preset);
    else this.setWaiting("The server holds no volume yet: open a study from the PACS, on the left, where it has one.");
  }

  async open(volumeId: string, preset?: string): Promise<void> {
    this.session?.close();
    this.showError("");
    this.showOpenVolume(volumeId);
    this.setWaiting(`Opening ${volumeId}…`);
    try {
      this.volume = await this.api.volumes.describeVolume({ volumeId });
      this.describeVolume();
      this.session = await LiveSession.create(this.api, this.handlers(), this.latency, volumeId,
                                              this.view.devicePixels(), preset);
      this.setWaiting("Waiting for the first frame…");
      this.share.show(true);
    } catch (e) {
      this.showError(plainWords(e));
    }
  }

  private async join(sessionId: string): Promise<void> {
    this.setWaiting("Joining the session…");
    try {
      this.session = await LiveSession.join(this.api, this.handlers(), this.latency, sessionId);
      this.setWaiting("Waiting for the first frame…");
      this.share.show(true);
      if (this.session.volumeId) {
        this.showOpenVolume(this.session.volumeId);
        this.volume = await this.api.volumes.describeVolume({ volumeId: this.session.volumeId });
        this.describeVolume();
      }
    } catch (e) {
      this.showError(plainWords(e));
    }
  }

  /**
   * A session shared with this page: watched with its grant, which allows no
   * volumes of one's own, no sharing and no reading tools (they name the
   * session, which only its owner may); the controls drive only while this
   * page presents. A link needs no token; the presets list needs one.
   */
  private watchShared(grant: string): void {
    for (const id of ["open", "reading"]) $(id).hidden = true;
    this.setDriving(false);
    this.setWaiting("Waiting for the shared session's first frame…");
    void this.api.server.getStatus({}).then((status) => {
      $<HTMLSelectElement>("preset").replaceChildren(...status.presets.map((p) => new Option(p, p)));
    }).catch(() => {});
    this.session = LiveSession.watchShared(this.api, this.handlers(), this.latency, grant);
  }

  /** The volume list shows the volume open (one from a PACS, or not listed yet, added to it). */
  private showOpenVolume(volumeId: string): void {
    const select = $<HTMLSelectElement>("volumes");
    if (![...select.options].some((o) => o.value === volumeId)) select.add(new Option(volumeId, volumeId));
    select.value = volumeId;
  }

  private handlers() {
    return {
      attached: (id: string) => id && history.replaceState(null, "", sessionQuery(location.search, id)),
      frame: (frame: Frame) => {
        this.lastFrame = frame;
        this.received.add(now(), frame.image.value?.byteLength ?? 0);
        this.view.show(frame);
      },
      state: (state: SessionState) => this.adopt(state),
      notice: (n: { message: string }) => this.setBanner(n.message, true),
      refused: (kinds: EventKind["case"][], error: ConnectError) => this.refused(kinds, error),
      banner: (text: string, passing?: boolean) => this.setBanner(text, passing),
      failed: (text: string, code?: Code) => {
        this.showError(text);
        $("presence").hidden = true;
        if (code === Code.Unauthenticated) this.onTokenRefused();
      },
    };
  }

  /**
   * Sends an event, where this page may: a pointer always; the viewport only
   * from the owner's window; the rest while it drives. Motion-to-photon
   * counts from the input event behind it (or now, for one without).
   */
  private post(kind: EventKind): void {
    const may = kind.case === "pointer" || (kind.case === "resize" ? !this.session?.grant : this.driving);
    if (!may) return;
    const t = now(), input = this.view.inputAt;
    this.session?.post(kind, t - input < INPUT_RECENT_MS ? input : t);
  }

  private refused(kinds: EventKind["case"][], error: ConnectError): void {
    if (error.code === Code.PermissionDenied && kinds.every((k) => k === "pointer")) {
      this.pointerRefused = true;
      this.setBanner("Your pointer is not shown to the others: this share does not allow it.", true);
      return;
    }
    this.setBanner(plainWords(error), true);
  }

  // ------------------------------------------------- a shared session

  /** This page's name as the server writes it (SessionState.presenter, pointers' `who`). */
  private ownName(): string | undefined {
    return this.echoedName ?? ownName(this.session?.owner, this.session?.grant ?? "");
  }

  /** Whether this page drives: the owner always (as the server lets it), a share's holder while it presents. */
  private presents(state: SessionState): boolean {
    return !this.session?.grant || (state.presenter !== "" && state.presenter === this.ownName());
  }

  /**
   * Before sharing: a named view's camera sent as its eye and target (the
   * same picture), so that a share's presenter, whose page knows no volume to
   * resolve the view with, can orbit from it.
   */
  private pinCamera(): void {
    const camera = this.state?.scene?.camera;
    if (camera && !camera.eye) this.moveCamera((c) => c);
  }

  private setDriving(on: boolean): void {
    this.driving = on;
    document.body.classList.toggle("watching", !on);
    for (const control of document.querySelectorAll<HTMLInputElement>(DRIVING)) control.disabled = !on;
    $("hand-back").hidden = !on || !this.session?.grant;
  }

  /** A share's presenter gives the role back to the owner. */
  private async handBack(): Promise<void> {
    try {
      await this.api.sessions.handOver({ grant: this.session?.grant ?? "", grantId: "" });
    } catch (e) {
      this.showError(shareWords(e));
    }
  }

  /** This page's pointer over the frame, while anyone watches: at most 20 a second, `null` once it leaves. */
  private point(at: Fraction | null): void {
    if (!this.state?.viewers || this.pointerRefused || (!at && !this.pointerSent)) return;
    this.pointer.push(at);
  }

  private sendPointer(at: Fraction | null): void {
    this.pointerSent = at ?? undefined;
    this.post({ case: "pointer", value: create(PointerSchema, at ? { x: at.x, y: at.y } : { hidden: true }) });
  }

  /** Who presents and how many watch; the share's list follows its watchers. */
  private adoptSharing(state: SessionState): void {
    const before = this.state;
    this.echoedName = echoedName(state.pointers, this.pointerSent) ?? this.echoedName;
    if (before && before.presenter !== state.presenter) this.pointerRefused = false;  // a hand-over may allow it now
    const driving = this.presents(state);
    if (driving !== this.driving) this.setDriving(driving);
    const line = presence(state, this.ownName(), Boolean(this.session?.grant));
    $("presence").textContent = line;
    $("presence").hidden = !line;
    if (before?.viewers !== state.viewers || before?.presenter !== state.presenter) void this.share.refresh();
  }

  // ------------------------------------------------------------ the state

  private adopt(state: SessionState): void {
    this.adoptSharing(state);
    this.state = state;
    const scene = state.scene;
    if (!scene) return;
    if (!this.session?.hasPending("camera")) this.camera = this.cameraOf(scene) ?? this.camera;
    if (this.session?.grant) this.reading.follow(scene.measurements);  // a watcher measures nothing of its own
    else this.reading.restore(scene.measurements);
    this.drawMarker();
    this.drawOverlay();
    $<HTMLSelectElement>("preset").value = scene.transferFunction?.preset ?? "";
    if (!this.session?.hasPending("transferFunction")) this.editor.show(scene.transferFunction);
    this.showLight(scene);
    this.showClipping(scene);
    this.showLabels(scene);
    $<HTMLInputElement>("lossless").checked = state.stream?.finalFormat === FinalFormat.PNG;
    $<HTMLInputElement>("quality").value = String(state.stream?.jpegQuality ?? 80);
  }

  private describeVolume(): void {
    this.home = undefined;
    this.editor.show(undefined, this.volume?.histogram);
    this.buildCropSliders();
    this.buildLabels();
    if (this.volume) this.reading.setVolume(this.volume);
    this.showIdentity();
  }

  /** A DICOM volume's patient, study and series in the 3D view's corners, unless the user hid them (F4). */
  private showIdentity(): void {
    const id = this.volume?.identity;
    $<HTMLInputElement>("show-identity").disabled = !id;
    const corners = id ? identityCorners(id) : { topLeft: [], topRight: [] };
    $("identity-top-left").textContent = corners.topLeft.join("\n");
    $("identity-top-right").textContent = corners.topRight.join("\n");
    $("identity").hidden = !id || !$<HTMLInputElement>("show-identity").checked;
  }

  // --------------------------------------------------------- the camera

  /**
   * The camera to orbit from: the state's own eye and target; for a named
   * view, what CreateSession resolved it to, else (a joined session) that
   * view around the volume's centre at twice its size.
   */
  private cameraOf(scene: Scene): ViewCamera | undefined {
    let c = scene.camera;
    const initial = this.session?.initialScene?.camera;
    if (c && !c.eye && c.view && initial?.view === c.view && initial.eye) c = initial;
    if (!c) return undefined;
    const fovYDeg = c.fovYDeg ?? 30;
    if (c.eye && c.target) return { eye: c.eye, target: c.target, up: c.up ?? v3(0, 0, 1), fovYDeg };
    if (!this.volume) return undefined;
    const box = patientBox(this.volume), patientFrame = scene.frame === SceneFrame.PATIENT_LPS;
    const size = len(sub(box.max, box.min));
    const target = patientFrame ? scale(add(box.min, box.max), 0.5) : v3(0, 0, 0);
    const around = { eye: add(target, v3(0, -2 * size, 0)), target, up: v3(0, 0, 1), fovYDeg };
    return namedView(around, NamedView[c.view || NamedView.ANTERIOR] as ViewName, this.volume.direction, patientFrame);
  }

  private moveCamera(move: (c: ViewCamera) => ViewCamera): void {
    const current = this.state?.scene?.camera;
    if (!this.camera || !current || !this.driving) return;
    this.home ??= this.camera;
    this.camera = move(this.camera);
    this.drawMarker();
    this.drawOverlay();
    const { eye, target, up, fovYDeg } = this.camera;
    const camera = create(CameraSchema, current);
    Object.assign(camera, { view: NamedView.NAMED_VIEW_UNSPECIFIED, eye: vec3(eye), target: vec3(target),
                            up: vec3(up), fovYDeg });
    this.post({ case: "camera", value: camera });
  }

  /** The orientation marker: the patient's axes as the camera sees them, the nearer drawn last. */
  private drawMarker(): void {
    const canvas = $<HTMLCanvasElement>("orientation"), g = canvas.getContext("2d");
    if (!g || !this.camera || !this.volume) return;
    const half = canvas.width / 2, reach = half * 0.62;
    g.clearRect(0, 0, canvas.width, canvas.height);
    g.lineWidth = 2;
    g.font = "bold 13px system-ui, sans-serif";
    g.textAlign = "center";
    g.textBaseline = "middle";
    const colour: Record<string, string> = { L: "#e66", R: "#e66", P: "#6c6", A: "#6c6", S: "#69f", I: "#69f" };
    for (const a of markerAxes(this.camera, this.volume.direction, this.state?.scene?.frame === SceneFrame.PATIENT_LPS)) {
      const x = half + a.x * reach, y = half - a.y * reach;
      g.globalAlpha = a.depth < 0 ? 0.45 : 1;
      g.strokeStyle = g.fillStyle = colour[a.letter];
      g.beginPath();
      g.moveTo(half, half);
      g.lineTo(x, y);
      g.stroke();
      g.fillText(a.letter, half + a.x * (reach + 10), half - a.y * (reach + 10));
    }
    g.globalAlpha = 1;
  }

  /**
   * Over the 3D view, where the frame shows: the slices' planes (2x2 layout)
   * and the measurements projected through the camera, and everyone else's
   * pointer in a shared session.
   */
  private drawOverlay(): void {
    const canvas = $<HTMLCanvasElement>("view-overlay"), view = $<HTMLCanvasElement>("view");
    const g = canvas.getContext("2d");
    if (!g) return;
    canvas.width = view.clientWidth;
    canvas.height = view.clientHeight;
    const rect = this.view.frameRect() ?? { left: 0, top: 0, width: canvas.width, height: canvas.height };
    this.drawPlanesAndMeasurements(g, rect);
    this.drawnPointers = othersPointers(this.state?.pointers ?? [], this.ownName());
    drawPointers(g, this.drawnPointers, rect);
  }

  private drawPlanesAndMeasurements(g: CanvasRenderingContext2D, rect: FrameRect): void {
    const camera = this.camera, volume = this.volume, patientFrame = this.state?.scene?.frame === SceneFrame.PATIENT_LPS;
    if (!camera || (!volume && !patientFrame)) return;  // a watcher knows no volume: a scene in patient space only
    const onView = (p: V3) => {
      const q = projectToView(camera, volume ? fromPatient(volume, patientFrame, p) : p, rect.width, rect.height);
      return q && { x: rect.left + q.x, y: rect.top + q.y };
    };
    g.lineWidth = 1.5;
    for (const plane of this.reading.slicePlanes()) {
      const points = plane.outline.map(onView);
      if (points.length === 0 || points.some((p) => !p)) continue;
      g.strokeStyle = PLANE_COLOURS[plane.axis] ?? "#ccc";
      g.beginPath();
      points.forEach((p, i) => (i ? g.lineTo(p!.x, p!.y) : g.moveTo(p!.x, p!.y)));
      g.closePath();
      g.stroke();
    }
    g.strokeStyle = g.fillStyle = "#4df";
    g.lineWidth = 2;
    g.font = "12px system-ui, sans-serif";
    for (const m of this.reading.measurements) {
      const points = m.points.map(onView);
      if (points.some((p) => !p)) continue;
      g.beginPath();
      points.forEach((p, i) => (i ? g.lineTo(p!.x, p!.y) : g.moveTo(p!.x, p!.y)));
      g.stroke();
      for (const p of points) g.fillRect(p!.x - 2, p!.y - 2, 4, 4);
      const last = points[points.length - 1]!;
      g.fillText(measurementText(m.points), last.x + 6, last.y - 6);
    }
  }

  private namedView(view: ViewName): void {
    const scene = this.state?.scene;
    if (!scene || !this.volume) return;
    this.moveCamera((c) => namedView(c, view, this.volume!.direction, scene.frame === SceneFrame.PATIENT_LPS));
  }

  private windowLevel(dx: number, dy: number): void {
    const tf = this.state?.scene?.transferFunction;
    if (!tf || tf.points.length === 0 || !this.volume || !this.driving) return;
    const range = this.volume.maxValue - this.volume.minValue || 1;
    this.post({ case: "transferFunction", value: applyWindowLevel(tf, (-dy * range) / 500, Math.exp(dx * 0.005)) });
  }

  // ---------------------------------------------------------- the light

  private keyLight(scene: Scene | undefined): { index: number; light: Light } | undefined {
    const index = scene?.lights.findIndex((l) => l.kind.case === "area") ?? -1;
    return index >= 0 ? { index, light: scene!.lights[index] } : undefined;
  }

  private showLight(scene: Scene): void {
    const key = this.keyLight(scene);
    $("light").hidden = !key;
    if (!key || key.light.kind.case !== "area" || !this.camera || this.session?.hasPending("lights")) return;
    const area = key.light.kind.value;
    const d = lightDirection({ center: area.center!, edgeU: area.edgeU!, edgeV: area.edgeV! }, this.camera);
    $<HTMLInputElement>("light-azimuth").value = String(Math.round(d.azimuthDeg));
    $<HTMLInputElement>("light-elevation").value = String(Math.round(d.elevationDeg));
    $<HTMLInputElement>("light-intensity").value = String(area.intensity);
  }

  private setLight(azimuthDeg: number, elevationDeg: number, intensity: number): void {
    const scene = this.state?.scene, key = this.keyLight(scene);
    if (!scene || !key || key.light.kind.case !== "area" || !this.camera) return;
    const area = key.light.kind.value;
    const pose = setLightDirection({ center: area.center!, edgeU: area.edgeU!, edgeV: area.edgeV! }, this.camera,
                                   azimuthDeg, elevationDeg);
    const turned = create(AreaLightSchema, { ...area, center: vec3(pose.center), edgeU: vec3(pose.edgeU),
                                             edgeV: vec3(pose.edgeV), intensity });
    const lights = scene.lights.map((l, i) =>
      i === key.index ? create(LightSchema, { kind: { case: "area", value: turned } }) : l);
    this.post({ case: "lights", value: create(LightListSchema, { lights }) });
  }

  private turnLight(dx: number, dy: number): void {
    if (!this.driving) return;
    const value = (id: string) => Number($<HTMLInputElement>(id).value);
    const azimuth = ((value("light-azimuth") + dx * DEGREES_PER_PIXEL + 540) % 360) - 180;
    const elevation = Math.max(-89, Math.min(89, value("light-elevation") - dy * DEGREES_PER_PIXEL));
    $<HTMLInputElement>("light-azimuth").value = String(azimuth);
    $<HTMLInputElement>("light-elevation").value = String(elevation);
    this.setLight(azimuth, elevation, value("light-intensity"));
  }

  // ------------------------------------------------------- crop and clip

  private buildCropSliders(): void {
    const holder = $("crop-sliders");
    holder.replaceChildren();
    for (const axis of AXES) {
      for (const end of ["lo", "hi"] as const) {
        const input = document.createElement("input");
        Object.assign(input, { type: "range", min: "0", max: "100", value: end === "lo" ? "0" : "100",
                               id: `crop-${axis}-${end}` });
        const name = `${AXIS_NAMES[axis]} crop ${end === "lo" ? "start" : "end"} (%)`;
        input.setAttribute("aria-label", name);
        input.title = name;
        input.addEventListener("input", () => this.sendClipping());
        holder.append(input);
      }
    }
  }

  private sendClipping(): void {
    if (!this.volume || !this.camera) return;
    const fraction = (axis: string, end: string) => Number($<HTMLInputElement>(`crop-${axis}-${end}`).value) / 100;
    const caps = $<HTMLInputElement>("caps").checked;
    const clipping = create(ClippingSchema, {});
    if ($<HTMLInputElement>("crop-on").checked) {
      const lo = v3(fraction("x", "lo"), fraction("y", "lo"), fraction("z", "lo"));
      const hi = v3(fraction("x", "hi"), fraction("y", "hi"), fraction("z", "hi"));
      const { center, size } = cropFromFractions(patientBox(this.volume), lo, hi);
      clipping.cropBox = create(CropBoxSchema, { center: vec3(center), size: vec3(size), cap: caps });
    }
    if ($<HTMLInputElement>("clip-on").checked) {
      const patientFrame = this.state?.scene?.frame === SceneFrame.PATIENT_LPS;
      const along = norm(toPatient(this.volume, patientFrame, sub(this.camera.target, this.camera.eye), true));
      const target = toPatient(this.volume, patientFrame, this.camera.target);
      const depth = Number($<HTMLInputElement>("clip-depth").value);
      clipping.planes = [create(ClipPlaneSchema, { point: vec3(add(target, scale(along, depth))), normal: vec3(along),
                                                   cap: caps })];
    }
    this.post({ case: "clipping", value: clipping });
  }

  private showClipping(scene: Scene): void {
    if (this.session?.hasPending("clipping")) return;
    $<HTMLInputElement>("crop-on").checked = Boolean(scene.clipping?.cropBox);
    $<HTMLInputElement>("clip-on").checked = (scene.clipping?.planes.length ?? 0) > 0;
  }

  // ------------------------------------------------------------- labels

  private buildLabels(): void {
    const names = this.volume?.labels?.names ?? [];
    $("labels-panel").hidden = names.length === 0 && !this.volume?.table?.voxels;
    $("labels").replaceChildren(...names.filter((n) => n.value !== 0).map((n) => {
      const item = document.createElement("li"), label = document.createElement("label");
      const box = Object.assign(document.createElement("input"), { type: "checkbox", checked: true });
      box.dataset.label = String(n.value);
      box.addEventListener("change", () => this.sendLabels());
      label.append(box, ` ${n.value} ${n.name || "(unnamed)"}`);
      item.append(label);
      return item;
    }));
  }

  private sendLabels(): void {
    const current = this.state?.scene?.labels;
    const styles = (current?.styles ?? []).map((s) => ({ ...s }));
    for (const box of document.querySelectorAll<HTMLInputElement>("#labels input[data-label]")) {
      const value = Number(box.dataset.label);
      let style = styles.find((s) => s.value === value);
      if (!style) styles.push(style = create(LabelStyleSchema, { value }));
      style.visible = box.checked;
    }
    this.post({ case: "labels", value: create(LabelsSchema, { ...current, styles,
                                                               removeTable: $<HTMLInputElement>("remove-table").checked }) });
  }

  private showLabels(scene: Scene): void {
    if (this.session?.hasPending("labels")) return;
    for (const box of document.querySelectorAll<HTMLInputElement>("#labels input[data-label]")) {
      const style = scene.labels?.styles.find((s) => s.value === Number(box.dataset.label));
      box.checked = style?.visible ?? true;
    }
    $<HTMLInputElement>("remove-table").checked = scene.labels?.removeTable ?? false;
  }

  // -------------------------------------------------------- the panels

  private wirePanels(): void {
    $("open-volume").addEventListener("click", () => void this.open($<HTMLSelectElement>("volumes").value));
    $("preset").addEventListener("change", () => {
      const preset = $<HTMLSelectElement>("preset").value;
      if (preset) this.post({ case: "transferFunction", value: create(TransferFunctionSchema, { preset }) });
    });
    for (const b of document.querySelectorAll<HTMLButtonElement>("[data-view]")) {
      b.addEventListener("click", () => this.namedView(b.dataset.view as ViewName));
    }
    $("home").addEventListener("click", () => this.goHome());
    for (const id of ["crop-on", "clip-on", "clip-depth", "caps"]) $(id).addEventListener("input", () => this.sendClipping());
    $("remove-table").addEventListener("change", () => this.sendLabels());
    for (const id of ["light-azimuth", "light-elevation", "light-intensity"]) {
      $(id).addEventListener("input", () => this.setLight(Number($<HTMLInputElement>("light-azimuth").value),
        Number($<HTMLInputElement>("light-elevation").value), Number($<HTMLInputElement>("light-intensity").value)));
    }
    $("lossless").addEventListener("change", () => this.post({ case: "stream", value: create(StreamSettingsSchema, {
      finalFormat: $<HTMLInputElement>("lossless").checked ? FinalFormat.PNG : FinalFormat.JPEG }) }));
    $("quality").addEventListener("change", () => this.post({ case: "stream", value: create(StreamSettingsSchema, {
      jpegQuality: Number($<HTMLInputElement>("quality").value) }) }));
    $("save-scene").addEventListener("click", () => this.saveScene());
    $("hand-back").addEventListener("click", () => void this.handBack());
    $("show-stats").addEventListener("change", () => { $("stats").hidden = !$<HTMLInputElement>("show-stats").checked; });
    $("show-identity").addEventListener("change", () => this.showIdentity());
    window.addEventListener("keydown", (e) => this.key(e));
  }

  /** The scene as the server has it, with this page's measurements: a file cinevol render, the viewer and a session open. */
  private saveScene(): void {
    const scene = this.state?.scene;
    if (!scene) return;
    const saved = create(SceneSchema, scene);
    saved.measurements = this.reading.measurements.map((m) => create(MeasurementSchema, { points: m.points.map(vec3) }));
    const link = document.createElement("a");
    link.href = URL.createObjectURL(new Blob([toJsonString(SceneSchema, saved, { prettySpaces: 2 })],
                                             { type: "application/json" }));
    link.download = "cinevol-scene.json";
    link.click();
    setTimeout(() => URL.revokeObjectURL(link.href), 1000);
  }

  private goHome(): void {
    const home = this.home;
    if (home) this.moveCamera(() => home);
  }

  /**
   * The desktop viewer's keys: F2 the statistics, F3 the 2x2 layout, F4 the
   * patient (wherever the keyboard is: no field types them); and, outside
   * the fields, A P L R S I named views, Home or Space the first view.
   */
  private key(e: KeyboardEvent): void {
    if (this.functionKey(e.key)) return e.preventDefault();
    const target = e.target as HTMLElement;
    if (target.matches("input:not([type=checkbox]):not([type=range]), select, textarea")) return;
    if (e.key === "Home" || e.key === " ") {
      this.goHome();
    } else if (!e.ctrlKey && !e.altKey && !e.metaKey && KEY_VIEWS[e.key.toLowerCase()] !== undefined) {
      this.namedView(KEY_VIEWS[e.key.toLowerCase()]);
    } else {
      return;
    }
    e.preventDefault();
  }

  /** F2, F3 and F4; false for any other key. */
  private functionKey(key: string): boolean {
    const toggle = (id: string) => {
      const box = $<HTMLInputElement>(id);
      box.checked = !box.checked;
    };
    if (key === "F2") {
      toggle("show-stats");
      $("stats").hidden = !$<HTMLInputElement>("show-stats").checked;
    } else if (key === "F3") {
      if (!this.session?.grant) this.reading.toggleLayout();  // a share's holder has no reading tools
    } else if (key === "F4") {
      toggle("show-identity");
      this.showIdentity();
    } else {
      return false;
    }
    return true;
  }

  // ------------------------------------------------- messages and stats

  /** Says how things are; a passing message clears itself unless another came meanwhile. */
  private setBanner(text: string, passing = false): void {
    this.remember(text);
    this.said.banner = text;
    this.showMessage();
    if (passing) setTimeout(() => this.said.banner === text && this.setBanner(""), PASSING_MS);
  }

  showError(text: string): void {
    this.remember(text);
    if (text) this.painted1st();  // nothing more will come to wait for
    this.said.error = text;
    this.showMessage();
  }

  /** What the page waits for, said while nothing else is; "" once there is a picture. */
  private setWaiting(text: string): void {
    this.said.waiting = text;
    this.showMessage();
  }

  /** One message at a time over the view: the error line (an alert) or the banner (a polite status). */
  private showMessage(): void {
    const shown = messageToShow(this.said);
    for (const kind of ["error", "banner"] as const) {
      $(kind).textContent = shown?.kind === kind ? shown.text : "";
      $(kind).hidden = shown?.kind !== kind;
    }
  }

  private remember(text: string): void {
    if (!text) return;
    this.messages.push(text);
    if (this.messages.length > 20) this.messages.shift();
  }

  private onPainted(meta: FrameMeta, at: number, decodeMs: number, replaced: number): void {
    this.painted1st();
    if (this.said.waiting) this.setWaiting("");
    this.frameIds.push(Number(meta.id));
    if (this.frameIds.length > 64) this.frameIds.shift();
    if (meta.width !== this.lastPainted?.width || meta.height !== this.lastPainted?.height) this.drawOverlay();
    this.decodeMs.push(decodeMs);
    if (this.decodeMs.length > 500) this.decodeMs.shift();
    this.lastPainted = meta;
    this.replaced = replaced;
    this.framesPainted += 1;
    this.painted.add(at);
    this.latency.painted(meta.lastEventSeq, at);
    if (this.framesPainted === 1) this.drawStats();
  }

  private drawStats(): void {
    const f = this.lastFrame, t = f?.timings, ms = (us = 0) => (us / 1000).toFixed(1);
    const samples = this.latency.samples;
    $("stats").textContent = f ? [
      `${f.width}x${f.height}  frame ${f.frameId}  ${f.accumulatedSpp} spp${f.final ? "  final" : ""}` +
        (f.resolutionScale < 1 ? `  scale ${f.resolutionScale}` : ""),
      `${this.painted.perSecond(now()).toFixed(1)} fps painted, ${this.replaced} replaced before painting`,
      `motion-to-photon p50 ${percentile(samples, 0.5).toFixed(0)} ms  p95 ${percentile(samples, 0.95).toFixed(0)} ms` +
        `  (${samples.length})`,
      `${(this.received.perSecond(now()) / 1e6).toFixed(2)} MB/s received, decode and draw p50 ` +
        `${percentile(this.decodeMs, 0.5).toFixed(1)} ms`,
      `server ms: render ${ms(t?.renderUs)} denoise ${ms(t?.denoiseUs)} tonemap ${ms(t?.tonemapUs)} ` +
        `encode ${ms(t?.encodeUs)} queue ${ms(t?.queueUs)} total ${ms(t?.serverUs)}`,
    ].join("\n") : "";  // before a frame the line over the view says what the page waits for
  }

  /** What tests and scripts read (window.cinevol). */
  status() {
    const samples = this.latency.samples;
    return {
      sessionId: this.session?.id ?? "", eventsSent: Number(this.session?.lastSeq ?? 0n), framesPainted: this.framesPainted,
      error: this.said.error, banner: this.said.banner, shown: messageToShow(this.said), messages: [...this.messages],
      lastFrame: this.lastPainted ? { ...this.lastPainted, id: Number(this.lastPainted.id),
                                       lastEventSeq: Number(this.lastPainted.lastEventSeq) } : null,
      motionToPhoton: { p50: percentile(samples, 0.5), p95: percentile(samples, 0.95), count: samples.length },
      decodeMs: { p50: percentile(this.decodeMs, 0.5), p95: percentile(this.decodeMs, 0.95) },
      fps: this.painted.perSecond(now()), bytesPerSecond: this.received.perSecond(now()),
      preset: this.state?.scene?.transferFunction?.preset ?? "",
      eventsByKind: { ...this.session?.sentKinds }, frameIds: [...this.frameIds],
      presenter: this.state?.presenter ?? "", viewers: this.state?.viewers ?? 0, driving: this.driving,
      pointers: this.drawnPointers.map((p) => ({ who: p.who, x: p.x, y: p.y })),
    };
  }
}
