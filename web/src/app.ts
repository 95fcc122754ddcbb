// The page once signed in: the volumes and PACS, a session on the 3D view
// and the rooms that show and edit it (navigation, transfer function,
// light, clipping, labels, output, reading, sharing, statistics, the line
// over the view); or a session shared with this page (#grant=), watched,
// and driven while this page presents. Every edit is an event to the
// server; every room shows the state the server answers (page_link.ts).
import { create } from "@bufbuild/protobuf";
import { Code, type ConnectError } from "@connectrpc/connect";
import { SceneSchema } from "../gen/cinevol/v1/scene_pb.js";
import { MeasurementListSchema, ViewportSchema, type Frame, type SessionState, type VolumeInfo } from "../gen/cinevol/v1/service_pb.js";
import type { Api } from "./api.js";
import { sessionQuery, type PageAddress } from "./address.js";
import { ClippingPanel } from "./clipping_panel.js";
import type { FrameMeta } from "./frame_messages.js";
import { listenToKeys } from "./keys.js";
import { LightPanel } from "./light_panel.js";
import { MessageLine } from "./message_line.js";
import { MoviePanel } from "./movie_panel.js";
import { Navigation, type ViewName } from "./navigation.js";
import { FusionPanel, fusedStart } from "./fusion_panel.js";
import { drawOverlay } from "./overlay.js";
import { PacsPanel } from "./pacs_panel.js";
import { PageLink } from "./page_link.js";
import { IdentityCorners, LabelsPanel, OutputPanel, sceneMeasurements } from "./panels.js";
import { Reading } from "./reading.js";
import type { EventKind, SessionStart } from "./session.js";
import { SharePanel } from "./share.js";
import { Sharing } from "./sharing.js";
import { StatsPanel } from "./stats_panel.js";
import { TimePanel } from "./time_panel.js";
import { TransferPanel } from "./transfer_panel.js";
import { View } from "./view.js";
import { plainWords } from "./words.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;

export class App {
  readonly view = new View($("view"));
  private readonly said = new MessageLine();
  private readonly stats = new StatsPanel();
  private readonly link: PageLink;
  private readonly navigation: Navigation;
  private readonly transfer: TransferPanel;
  private readonly time: TimePanel;
  private readonly fusion: FusionPanel;
  private readonly light: LightPanel;
  private readonly clipping: ClippingPanel;
  private readonly labels: LabelsPanel;
  private readonly output: OutputPanel;
  private readonly identity = new IdentityCorners();
  private readonly reading: Reading;
  private readonly share: SharePanel;
  private readonly sharing: Sharing;
  private painted1st!: () => void;
  /** The server refused the page's token (or a user's share came without one): main.ts asks for one. */
  onTokenRefused: () => void = () => {};
  /** Settles with the first frame painted, or with a failure shown. */
  readonly firstPaint = new Promise<void>((resolve) => { this.painted1st = resolve; });

  constructor(private readonly api: Api) {
    this.said.onError = () => this.painted1st();  // nothing more will come to wait for
    this.link = new PageLink(api, this.handlers(), this.said, this.stats.latency, () => this.view.inputAt);
    const link = this.link, camera = () => this.navigation.camera;
    this.navigation = new Navigation(link);
    this.navigation.onMoved = () => this.drawOverlay();
    this.transfer = new TransferPanel(link);
    this.time = new TimePanel(link);
    this.fusion = new FusionPanel(link, (volumeId) => this.api.volumes.describeVolume({ volumeId }));
    this.light = new LightPanel(link, camera);
    this.clipping = new ClippingPanel(link, camera);
    this.labels = new LabelsPanel(link);
    this.reading = new Reading(api, () => link.session?.id, (text) => this.said.showError(text));
    this.reading.onOverlayChanged = () => this.drawOverlay();
    this.reading.onNotice = (text) => this.said.setBanner(text, true);
    this.reading.onMeasurementsEdited = (list) => link.post({ case: "measurements", value: create(MeasurementListSchema, {
      measurements: sceneMeasurements(list) }) });
    this.output = new OutputPanel(link, () => this.reading.measurements);
    new MoviePanel(api, () => link.session?.id, (text) => this.said.setBanner(text), (text) => this.said.showError(text));
    this.share = new SharePanel(api, () => link.session?.id, (text) => this.said.showError(text));
    this.sharing = new Sharing(link, this.share, this.said);
    this.listen();
  }

  /** Fills the lists, then opens what the address names. Throws (in words) when the token is refused. */
  async boot(address: PageAddress): Promise<void> {
    if (address.grant) return this.watchShared(address.grant);
    const status = await this.api.server.getStatus({});
    this.transfer.offer(status.presets, true);
    const volumes = await this.api.volumes.listVolumes({});
    $<HTMLSelectElement>("volumes").replaceChildren(...volumes.volumes.map((v) => new Option(v.id, v.id)));
    const pacs = new PacsPanel(this.api, {
      loaded: (volume, scene) => void this.open(volume.id, { scene }),
      measured: (measurements) => this.measure(measurements),
      sessionId: () => this.link.session?.id,
      volumeId: () => this.link.session?.volumeId,
      banner: (t) => this.said.setBanner(t),
      error: (t) => this.said.showError(t),
    });
    const listed = pacs.start();
    // An address that names no volume opens the server's first, as the desktop viewer does: never a blank view.
    const volumeId = address.volume ?? volumes.volumes[0]?.id;
    if (address.session) await this.join(address.session);
    else if (address.iid) await listed.then(() => pacs.openIid(address.iid!));
    else if (volumeId && address.fuse) await this.openFused(volumeId, address, volumes.volumes);
    else if (volumeId) await this.open(volumeId, { preset: address.preset });
    else this.said.setWaiting("The server holds no volume yet: open a study from the PACS, on the left, where it has one.");
  }

  /** Measurements from a report: the page's own from now on, and the session's. */
  private measure(measurements: readonly { points: readonly { x: number; y: number; z: number }[] }[]): void {
    this.reading.follow(measurements);
    this.reading.onMeasurementsEdited(this.reading.measurements);
  }

  /** `fuse=ID`: the volume with a second one over it, glowing in 3D and coloured over the slices. */
  private async openFused(volumeId: string, address: PageAddress, volumes: readonly VolumeInfo[]): Promise<void> {
    const fused = volumes.find((v) => v.id === address.fuse);
    if (!fused) return this.said.showError(`The server holds no volume '${address.fuse}' to fuse (fuse=).`);
    this.fusion.setFused(fused);
    const scene = create(SceneSchema, {
      transferFunction: { preset: address.preset ?? "" }, fusion: fusedStart(fused, address.alignByPatient ?? false),
    });
    await this.open(volumeId, { scene });
  }

  async open(volumeId: string, start: SessionStart = {}): Promise<void> {
    this.showOpenVolume(volumeId);
    if (await this.link.open(volumeId, this.view.devicePixels(), start)) this.share.show(true);
  }

  private async join(sessionId: string): Promise<void> {
    if (!(await this.link.join(sessionId))) return;
    this.share.show(true);
    if (this.link.session?.volumeId) this.showOpenVolume(this.link.session.volumeId);
  }

  /**
   * A session shared with this page: watched with its grant, which allows no
   * volumes of one's own, no sharing and no reading tools (they name the
   * session, which only its owner may); the controls drive only while this
   * page presents. A link needs no token; the presets list needs one.
   */
  private watchShared(grant: string): void {
    for (const id of ["open", "reading"]) $(id).hidden = true;
    this.sharing.setDriving(false);
    void this.api.server.getStatus({}).then((status) => this.transfer.offer(status.presets, false)).catch(() => {});
    this.link.watchShared(grant);
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
        this.stats.arrived(frame);
        this.view.show(frame);
        this.time.shown(frame);
      },
      state: (state: SessionState) => this.adopt(state),
      volume: (volume: VolumeInfo | undefined) => this.describeVolume(volume),
      notice: (n: { message: string }) => this.said.setBanner(n.message, true),
      refused: (kinds: EventKind["case"][], error: ConnectError) => {
        if (!this.sharing.refusedPointer(kinds, error)) this.said.setBanner(plainWords(error), true);
      },
      banner: (text: string, passing?: boolean) => this.said.setBanner(text, passing),
      failed: (text: string, code?: Code) => {
        this.said.showError(text);
        $("presence").hidden = true;
        if (code === Code.Unauthenticated) this.onTokenRefused();
      },
    };
  }

  /** A state from the server: every room shows it (each keeps its own edit while that is newer). */
  private adopt(state: SessionState): void {
    this.sharing.adopt(state);
    const scene = state.scene;
    if (!scene) return;
    this.navigation.adopt(state);
    this.reading.place(this.link.placement);
    if (this.link.shared) this.reading.follow(scene.measurements);  // a watcher measures nothing of its own
    else this.reading.restore(scene.measurements);
    this.drawOverlay();
    this.transfer.adopt(state);
    this.time.show(scene);
    this.fusion.show(scene);
    this.light.show(scene);
    this.clipping.show(scene);
    this.labels.show(scene);
    this.output.show(state);
  }

  private describeVolume(volume: VolumeInfo | undefined): void {
    this.navigation.reset();
    this.transfer.setVolume(volume);
    this.time.setVolume(volume);
    this.clipping.reset();
    this.labels.setVolume(volume);
    if (volume) this.reading.setVolume(volume);
    this.identity.setVolume(volume);
  }

  private listen(): void {
    const nav = this.navigation;
    this.view.onPainted = (meta, at, decodeMs, replaced) => this.onPainted(meta, at, decodeMs, replaced);
    this.view.onError = (text) => this.said.showError(text);
    this.view.listen({
      orbit: (dx, dy) => nav.orbit(dx, dy),
      pan: (dx, dy, h) => nav.pan(dx, dy, h),
      zoom: (f) => nav.zoom(f),
      windowLevel: (dx, dy) => this.transfer.windowLevel(dx, dy),
      turnLight: (dx, dy) => this.light.turn(dx, dy),
      pick: (fx, fy, frame) => {
        // Not by a share: Pick, as RenderSlice, names the session, which only its owner may.
        if (!this.link.shared) void this.reading.pickOnView(fx * frame.width, fy * frame.height, frame);
      },
      point: (at) => this.sharing.point(at),
    });
    this.view.followSize((size) => this.link.post({ case: "resize", value: create(ViewportSchema, size) }));
    $("open-volume").addEventListener("click", () => void this.open($<HTMLSelectElement>("volumes").value));
    for (const b of document.querySelectorAll<HTMLButtonElement>("[data-view]")) {
      b.addEventListener("click", () => nav.namedView(b.dataset.view as ViewName));
    }
    $("home").addEventListener("click", () => nav.goHome());
    listenToKeys({
      statistics: () => this.stats.toggle(),
      layout: () => { if (!this.link.shared) this.reading.toggleLayout(); },  // a share's holder has no reading tools
      identity: () => this.identity.toggle(),
      home: () => nav.goHome(),
      namedView: (view) => nav.namedView(view),
    });
  }

  private drawOverlay(): void {
    drawOverlay({
      frame: this.view.frameRect(), camera: this.navigation.camera, placement: this.link.placement,
      planes: this.reading.slicePlanes(), measurements: this.reading.measurements, pointers: this.sharing.others(),
    });
  }

  private onPainted(meta: FrameMeta, at: number, decodeMs: number, replaced: number): void {
    this.painted1st();
    if (this.said.waiting) this.said.setWaiting("");
    const before = this.stats.lastPainted;
    if (meta.width !== before?.width || meta.height !== before?.height) this.drawOverlay();
    this.stats.painted(meta, at, decodeMs, replaced);
  }

  showError(text: string): void {
    this.said.showError(text);
  }

  /** What tests and scripts read (window.cinevol). */
  status() {
    const state = this.link.state, session = this.link.session, c = this.navigation.camera;
    return {
      ...this.stats.status(),
      sessionId: session?.id ?? "", eventsSent: Number(session?.lastSeq ?? 0n),
      error: this.said.error, banner: this.said.banner, shown: this.said.shown, messages: this.said.messages,
      preset: state?.scene?.transferFunction?.preset ?? "",
      eventsByKind: { ...session?.sentKinds },
      presenter: state?.presenter ?? "", viewers: state?.viewers ?? 0, driving: this.link.driving,
      pointers: this.sharing.others().map((p) => ({ who: p.who, x: p.x, y: p.y })),
      camera: c ? { eye: c.eye, target: c.target, up: c.up } : null,
    };
  }
}
