// Sharing a session end to end (page.test.ts runs it in its order): alice
// shares a link from the Share panel; its viewer watches, points, cannot
// drive until made presenter, and is cut off when revoked; a user's share
// needs that user's token.
import assert from "node:assert/strict";
import { join } from "node:path";
import { test } from "node:test";
import {
  ARTIFACTS, base, drag, framesAfter, meanDifference, run, sample, settled, sleep, status, until, WAIT, waitForText,
} from "./page_harness.js";

export function sharingTests(): void {
  test("sharing: a link's viewer watches alice's session, points, cannot drive until made presenter, and is cut off when revoked",
       async () => {
    const { browser } = run;
    const owner = await browser.newPage({ viewport: { width: 900, height: 540 } });
    await owner.goto(`${base()}/?volume=phantom:head#token=alice-token`);
    await until(owner, (s) => s.framesPainted >= 2, "alice's session");
    // The Share panel: a link, as a viewer, for 15 minutes, pointer allowed.
    await owner.click("#share summary");
    await owner.selectOption("#share-role", "1");
    await owner.selectOption("#share-expires", "900");
    await owner.check("#share-pointer");
    await owner.click("#share-create");
    await owner.waitForFunction(() => (document.getElementById("share-link") as HTMLInputElement).value !== "", null, WAIT);
    const link = await owner.inputValue("#share-link");
    assert.match(link, new RegExp(`^${base()}/#grant=cvg_[^&]+$`), "the secret rides in the fragment");
    const grant = decodeURIComponent(link.split("#grant=")[1]);
    await waitForText(owner, "#share-grants", /link g\w+ · viewer · pointer · expires in 1[45] min · 0 watching/);

    // The viewer: no token, a window of another size; the session's frames as alice's page paints them.
    const viewer = await browser.newPage({ viewport: { width: 800, height: 500 } });
    await viewer.goto(link, { waitUntil: "domcontentloaded" });
    await waitForText(viewer, "#presence", /^Watching alice · 1 viewer$/);
    assert.ok(!viewer.url().includes("grant"), "the secret leaves the address bar");
    await waitForText(owner, "#presence", /^Shared · 1 viewer$/);
    await waitForText(owner, "#share-grants", /1 watching/);
    await drag(owner, 60, 0);  // alice turns it a little: frames for both, whatever refinement had reached
    let common: number[] = [];
    for (const end = Date.now() + WAIT.timeout; common.length < 2 && Date.now() < end; await sleep(200)) {
      const [a, v] = [await status(owner), await status(viewer)];
      common = a.frameIds.filter((id) => v.frameIds.includes(id));
    }
    assert.ok(common.length >= 2, `the viewer paints frames alice's page paints: ${JSON.stringify(common)}`);
    const aliceFrame = (await status(owner)).lastFrame!, viewerFrame = (await status(viewer)).lastFrame!;
    assert.deepEqual([viewerFrame.width, viewerFrame.height], [aliceFrame.width, aliceFrame.height],
                     "the session's frames, not the viewer's window");
    await viewer.screenshot({ path: join(ARTIFACTS, "10-viewer.png") });

    // The viewer's controls are off, its drag sends nothing, and the server refuses a viewer's camera anyway.
    assert.equal(await viewer.isDisabled("#preset"), true);
    assert.equal(await viewer.isHidden("#share"), true);
    await settled(owner);  // alice's own turn shown: from here only refinement changes her picture
    const still = [await sample(owner), await sleep(1500).then(() => sample(owner))];
    const noise = meanDifference(still[0].grid, still[1].grid);
    await drag(viewer, 200, 40);
    await sleep(1500);
    const after = await sample(owner), aliceNow = await status(owner);
    assert.ok(meanDifference(still[1].grid, after.grid) <= 3 * noise + 2,
              `alice's picture moved by the viewer's drag: ${meanDifference(still[1].grid, after.grid).toFixed(2)} ` +
              `(refinement alone: ${noise.toFixed(2)})`);
    assert.ok(aliceNow.lastFrame!.lastEventSeq <= aliceNow.eventsSent, "no event but alice's own in her frames");
    assert.equal((await status(viewer)).eventsByKind.camera ?? 0, 0, "no camera sent by a viewer");
    const refused = await fetch(`${base()}/cinevol.v1.SessionService/SendEvents`, {
      method: "POST", headers: { "content-type": "application/json" },
      body: JSON.stringify({ grant, events: [{ seq: "1", camera: { view: "LEFT" } }] }),
    });
    assert.equal(refused.status, 403, await refused.text());

    // Pointers: the viewer's on alice's page where it points on its own; alice's on the viewer's, and neither on its own.
    const vbox = (await viewer.locator("#view").boundingBox())!;
    const fit = Math.min(vbox.width / aliceFrame.width, vbox.height / aliceFrame.height);  // the frame shown whole, centred
    const onFrame = (fx: number, fy: number) => [vbox.x + (vbox.width - aliceFrame.width * fit) / 2 + fx * aliceFrame.width * fit,
                                                 vbox.y + (vbox.height - aliceFrame.height * fit) / 2 + fy * aliceFrame.height * fit];
    await viewer.mouse.move(...(onFrame(0.5, 0.5) as [number, number]));
    await viewer.mouse.move(...(onFrame(0.25, 0.75) as [number, number]), { steps: 5 });
    const pointed = await until(owner, (s) => s.pointers.some((p) => p.who.startsWith("link ") && Math.abs(p.x - 0.25) < 0.02 &&
                                                       Math.abs(p.y - 0.75) < 0.02), "the viewer's pointer on alice's page");
    assert.equal(pointed.pointers.length, 1, JSON.stringify(pointed.pointers));
    await owner.screenshot({ path: join(ARTIFACTS, "11-viewer-pointer-on-alice.png") });
    const obox = (await owner.locator("#view").boundingBox())!;
    await owner.mouse.move(obox.x + obox.width * 0.6, obox.y + obox.height * 0.4, { steps: 5 });
    const seen = await until(viewer, (s) => s.pointers.some((p) => p.who === "alice"), "alice's pointer on the viewer's page");
    assert.ok(!seen.pointers.some((p) => p.who.startsWith("link ")), "the viewer's own pointer is not drawn for it");
    assert.ok(!(await status(owner)).pointers.some((p) => p.who === "alice"), "nor alice's for her");
    await viewer.mouse.move(vbox.x - 50, vbox.y + 10);  // onto the panel: it leaves the view, and alice's
    await until(owner, (s) => !s.pointers.some((p) => p.who.startsWith("link ")), "the viewer's pointer hidden on leaving");

    // Made presenter, the viewer drives alice's picture; taken back, it watches again.
    await owner.click("#share-grants button:text('Make presenter')");
    await until(viewer, (s) => s.driving && /^link /.test(s.presenter), "the viewer presenting");
    await waitForText(viewer, "#presence", /^You present/);
    await waitForText(owner, "#presence", /^link g\w+ presents · 1 viewer$/);
    assert.equal((await status(owner)).driving, true, "the owner may always drive");
    const before = await sample(owner);
    await drag(viewer, 200, 40);
    await until(viewer, (s) => (s.eventsByKind.camera ?? 0) > 0, "the presenter's camera sent");
    await framesAfter(owner, 4);
    const turned = await sample(owner);
    assert.ok(meanDifference(before.grid, turned.grid) > 3 * noise + 2,
              `the presenter's drag left alice's picture as it was: ${meanDifference(before.grid, turned.grid).toFixed(2)}`);
    await owner.click("#share-take-back");
    await until(viewer, (s) => !s.driving && s.presenter === "alice", "the role taken back");
    await waitForText(viewer, "#presence", /^Watching alice/);

    // Revoked: the viewer's stream ends at once, in plain words.
    await owner.click("#share-grants button:text('Revoke')");
    await waitForText(viewer, "#error", /share has ended: its owner revoked it/);
    await viewer.screenshot({ path: join(ARTIFACTS, "12-viewer-revoked.png") });
    await until(owner, (s) => s.viewers === 0, "no viewer left");
    await owner.waitForFunction(() => document.querySelectorAll("#share-grants li").length === 0, null, WAIT);
    await viewer.close();

    // A user's share: their token too; without it the page asks for one.
    await owner.fill("#share-principal", "bob");
    await owner.click("#share-create");
    await owner.waitForFunction((l) => (document.getElementById("share-link") as HTMLInputElement).value !== l, link, WAIT);
    const bobLink = await owner.inputValue("#share-link");
    const bob = await browser.newPage({ viewport: { width: 640, height: 480 } });
    await bob.goto(`${bobLink}&token=bob-token`, { waitUntil: "domcontentloaded" });
    await waitForText(bob, "#presence", /^Watching alice · 1 viewer$/);
    await bob.close();
    const anonymous = await browser.newPage({ viewport: { width: 640, height: 480 } });
    await anonymous.goto(bobLink, { waitUntil: "domcontentloaded" });
    await waitForText(anonymous, "#error", /your own token/);
    assert.ok(await anonymous.isVisible("#sign-in"), "the sign-in form is offered");
    await anonymous.close();
    await owner.close();
  });
}
