// fidlearn's camera widget: the browser's camera (getUserMedia) to the kernel, frame by frame.
// Plain ES module for anywidget: no build step, no network. The Python side is fidlearn/_webcam.py.
//
// Messages from the kernel:   {type: "snap", id, format, quality}  -> one frame, answered with
//                             {type: "frame", kind: "snap", id, width, height, format} + [bytes]
//                             {type: "ack", seq, wait_ms}          -> the kernel has handled stream
//                             frame `seq`; the next one may leave after wait_ms (back-pressure).
// While the trait `streaming` is true, one stream frame is in flight at a time:
//                             {type: "frame", kind: "stream", seq, width, height, format} + [bytes]

const FAILURES = {
  NotAllowedError: "denied",
  SecurityError: "denied",
  PermissionDeniedError: "denied",
  NotFoundError: "no-camera",
  DevicesNotFoundError: "no-camera",
  OverconstrainedError: "no-camera",
  NotReadableError: "busy",
  TrackStartError: "busy",
  AbortError: "busy",
};

function cameraState(model) {
  // One camera per widget model, shared by all its views.
  if (!model.__fidlearnCamera) {
    model.__fidlearnCamera = {
      video: null, stream: null, opening: null, seq: 0, inFlight: false, timer: null, canvas: null,
    };
  }
  return model.__fidlearnCamera;
}

function setStatus(model, status, detail) {
  model.set("status", status);
  model.set("error", detail || "");
  model.save_changes();
}

async function openCamera(model) {
  const cam = cameraState(model);
  if (cam.stream) return cam;
  if (cam.opening) return cam.opening;
  cam.opening = (async () => {
    if (!window.isSecureContext) {
      setStatus(model, "insecure", `this page (${location.protocol}//${location.host}) is not a secure context`);
      throw new Error("insecure context");
    }
    if (!navigator.mediaDevices || !navigator.mediaDevices.getUserMedia) {
      setStatus(model, "no-camera", "this browser offers no navigator.mediaDevices.getUserMedia");
      throw new Error("no getUserMedia");
    }
    setStatus(model, "starting", "");
    let stream;
    try {
      stream = await navigator.mediaDevices.getUserMedia({
        audio: false,
        video: { width: { ideal: model.get("width") }, height: { ideal: model.get("height") } },
      });
    } catch (err) {
      setStatus(model, FAILURES[err.name] || "error", `${err.name}: ${err.message}`);
      throw err;
    }
    const video = document.createElement("video");
    video.muted = true;
    video.playsInline = true;
    video.srcObject = stream;
    await video.play();
    while (!video.videoWidth) await new Promise((r) => setTimeout(r, 20));
    cam.video = video;
    cam.stream = stream;
    cam.canvas = document.createElement("canvas");
    reportSize(model, cam);
    model.set("status", "streaming");
    model.set("error", "");
    model.save_changes();
    return cam;
  })();
  try {
    return await cam.opening;
  } finally {
    cam.opening = null;
  }
}

function reportSize(model, cam) {
  model.set("actual_width", cam.video.videoWidth);
  model.set("actual_height", cam.video.videoHeight);
  model.save_changes();
}

async function resize(model) {
  const cam = cameraState(model);
  if (!cam.stream) return;
  const track = cam.stream.getVideoTracks()[0];
  try {
    await track.applyConstraints({ width: { ideal: model.get("width") }, height: { ideal: model.get("height") } });
  } catch (err) {
    setStatus(model, "streaming", `the camera refused ${model.get("width")}x${model.get("height")}: ${err.name}`);
  }
  const start = performance.now();
  // The video element takes a frame or two to change size.
  while (performance.now() - start < 2000) {
    const s = track.getSettings();
    if (cam.video.videoWidth === s.width && cam.video.videoHeight === s.height) break;
    await new Promise((r) => setTimeout(r, 50));
  }
  reportSize(model, cam);
}

async function grab(cam, format, quality) {
  const { video, canvas } = cam;
  canvas.width = video.videoWidth;
  canvas.height = video.videoHeight;
  const ctx = canvas.getContext("2d");
  ctx.drawImage(video, 0, 0);
  const type = format === "png" ? "image/png" : "image/jpeg";
  const blob = await new Promise((resolve) => canvas.toBlob(resolve, type, quality));
  return { width: canvas.width, height: canvas.height, bytes: await blob.arrayBuffer() };
}

async function sendSnapshot(model, msg) {
  let cam;
  try {
    cam = await openCamera(model);
  } catch (err) {
    model.send({ type: "frame", kind: "snap", id: msg.id, failed: model.get("status"), error: model.get("error") });
    return;
  }
  const f = await grab(cam, msg.format, msg.quality);
  model.send({ type: "frame", kind: "snap", id: msg.id, width: f.width, height: f.height, format: msg.format }, undefined, [f.bytes]);
}

async function streamOne(model) {
  const cam = cameraState(model);
  cam.timer = null;
  if (!model.get("streaming") || cam.inFlight || !cam.stream) return;
  cam.inFlight = true;
  cam.seq += 1;
  const format = model.get("stream_format");
  const f = await grab(cam, format, model.get("jpeg_quality"));
  model.send({ type: "frame", kind: "stream", seq: cam.seq, width: f.width, height: f.height, format }, undefined, [f.bytes]);
}

function onMessage(model, msg) {
  const cam = cameraState(model);
  if (msg.type === "snap") {
    sendSnapshot(model, msg);
  } else if (msg.type === "ack" && msg.seq === cam.seq) {
    cam.inFlight = false;
    if (cam.timer) clearTimeout(cam.timer);
    cam.timer = setTimeout(() => streamOne(model), Math.max(0, msg.wait_ms || 0));
  }
}

function onStreaming(model) {
  const cam = cameraState(model);
  if (model.get("streaming")) {
    cam.inFlight = false; // a frame lost before stop() must not block a new start()
    openCamera(model).then(() => streamOne(model), () => {});
  } else if (cam.timer) {
    clearTimeout(cam.timer);
    cam.timer = null;
  }
}

function initialize({ model }) {
  const handler = (msg) => onMessage(model, msg);
  const streaming = () => onStreaming(model);
  const sized = () => resize(model);
  model.on("msg:custom", handler);
  model.on("change:streaming", streaming);
  model.on("change:width", sized);
  model.on("change:height", sized);
  return () => {
    model.off("msg:custom", handler);
    model.off("change:streaming", streaming);
    model.off("change:width", sized);
    model.off("change:height", sized);
    const cam = cameraState(model);
    if (cam.timer) clearTimeout(cam.timer);
    if (cam.stream) cam.stream.getTracks().forEach((t) => t.stop());
  };
}

function render({ model, el }) {
  el.classList.add("fidlearn-webcam");
  const video = document.createElement("video");
  video.muted = true;
  video.playsInline = true;
  video.autoplay = true;
  const caption = document.createElement("div");
  caption.className = "fidlearn-webcam-caption";
  const message = document.createElement("div");
  message.className = "fidlearn-webcam-message";
  el.append(video, caption, message);

  const update = () => {
    const status = model.get("status");
    const ok = status === "streaming";
    video.style.display = ok ? "block" : "none";
    video.style.maxWidth = `${model.get("display_width")}px`;
    message.style.display = ok && !model.get("error") ? "none" : "block";
    message.textContent = model.get("message");
    caption.textContent = ok
      ? `camera: ${model.get("actual_width")} x ${model.get("actual_height")} px` +
        (model.get("streaming") ? ", streaming to the kernel" : "")
      : "";
    const cam = cameraState(model);
    if (ok && cam.stream && video.srcObject !== cam.stream) video.srcObject = cam.stream;
  };
  const names = ["change:status", "change:message", "change:error", "change:actual_width", "change:actual_height",
    "change:streaming", "change:display_width"];
  names.forEach((n) => model.on(n, update));
  update();
  openCamera(model).then(update, update);
  return () => names.forEach((n) => model.off(n, update));
}

export default { initialize, render };
