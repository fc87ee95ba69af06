// The gateway's page: a photo goes to POST /v1/query with the device's token; the answer shows
// the matched place (its stored picture beside the photo, which robot saw it when, how sure);
// what changed there is boxed on the photo; the site overview (robots, loop closures, scene-change
// alarms with their pictures) polls GET /v1/site. Plain JavaScript, no build step.
'use strict';

const $ = (id) => document.getElementById(id);
let token = '';

function setToken(value) {
  token = value.trim();
  if (token) localStorage.setItem('placerec-token', token);
  $('token-state').textContent = token ? 'Token set.' : 'No token: ask your operator for one.';
}

function authHeaders() {
  return { Authorization: 'Bearer ' + token };
}

function when(utime) {
  return new Date(utime / 1000).toLocaleString();
}

function text(tag, content, className) {
  const element = document.createElement(tag);
  element.textContent = content;
  if (className) element.className = className;
  return element;
}

async function errorOf(response) {
  try {
    const body = await response.json();
    return body.error || ('HTTP ' + response.status);
  } catch (e) {
    return 'HTTP ' + response.status;
  }
}

async function showThumbnail(match) {
  const img = $('theirs');
  img.removeAttribute('src');
  $('theirs-caption').textContent = 'The matched place';
  const response = await fetch(match.thumbnail, { headers: authHeaders() });
  if (!response.ok) {
    $('theirs-caption').textContent = 'No stored picture of this place (' + await errorOf(response) + ')';
    return;
  }
  img.src = URL.createObjectURL(await response.blob());
  $('theirs-caption').textContent = 'Place #' + match.place_id + ' as ' + match.robot + ' saw it';
}

// What changed at the place: boxes over the photo (their pixels are the photo's as sent) and a
// line for each change.
function describeChange(c) {
  const what = c.kind === 'appeared' ? 'appeared' : 'gone';
  return (c.class || 'object') + ' ' + what + ' (' + Math.round(100 * c.confidence) + ' % sure)';
}

function showChanges(answer) {
  const frame = $('mine-frame');
  frame.querySelectorAll('.change-box').forEach((b) => b.remove());
  const changes = answer.changes || [];
  const place = () => {
    const img = $('mine');
    if (!img.naturalWidth) return;
    for (const c of changes) {
      const b = document.createElement('div');
      b.className = 'change-box';
      b.title = describeChange(c);
      b.style.left = (100 * c.box.x / img.naturalWidth) + '%';
      b.style.top = (100 * c.box.y / img.naturalHeight) + '%';
      b.style.width = (100 * c.box.width / img.naturalWidth) + '%';
      b.style.height = (100 * c.box.height / img.naturalHeight) + '%';
      frame.append(b);
    }
  };
  if ($('mine').complete) place(); else $('mine').addEventListener('load', place, { once: true });
  if (!answer.change_checked) return null;
  return changes.length ? 'Changed since then: ' + changes.map(describeChange).join('; ')
                        : 'Nothing changed there since then.';
}

function showAnswer(answer) {
  const box = $('answer');
  box.replaceChildren();
  $('mine-frame').querySelectorAll('.change-box').forEach((b) => b.remove());
  if (!answer.matches.length) {
    box.append(text('p', 'Not recognised: no stored place looks like this photo.', 'verdict none'));
    return;
  }
  const best = answer.matches[0];
  const sure = answer.loop_closure;
  box.append(text('p', (sure ? 'Recognised: ' : 'Perhaps: ') + 'place #' + best.place_id +
                  ', seen by robot ' + best.robot + ' on ' + when(best.utime),
                  'verdict ' + (sure ? 'sure' : 'unsure')));
  const details = 'score ' + best.score.toFixed(0) + ' (geometric inliers), ' +
      best.matched_landmarks + ' landmarks matched' +
      (best.classes.length ? ': ' + best.classes.map((c) => c.class + ' x' + c.count).join(', ') : '') +
      (sure ? '' : '; below the server\'s loop-closure threshold');
  box.append(text('p', details, 'hint'));
  if (answer.matches.length > 1) {
    const others = answer.matches.slice(1, 4).map((m) => '#' + m.place_id + ' (' + m.robot +
                                                   ', score ' + m.score.toFixed(0) + ')');
    box.append(text('p', 'Other candidates: ' + others.join(', '), 'hint'));
  }
  const changed = showChanges(answer);
  if (changed) box.append(text('p', changed, 'changes'));
  showThumbnail(best);
}

// A phone's photo (3-12 MB at 12 megapixels) goes as a JPEG the size the server processes it
// at: at most this wide and this squared in pixels (the server's --max-image-width default).
// The gateway hands it to the server over LCM, whose UDP multicast loses frames of megabytes,
// and pixels beyond it would only be scaled away.
const kMaxPhotoWidth = 960;

// The photo to send: `file` itself when it is small, else a smaller JPEG of it (the browser turns
// it upright by its EXIF orientation); `file` too when the browser cannot decode it (the gateway
// then says what is wrong).
async function shrink(file) {
  try {
    const bitmap = await createImageBitmap(file);
    const scale = Math.min(1, kMaxPhotoWidth / bitmap.width,
                           kMaxPhotoWidth / Math.sqrt(bitmap.width * bitmap.height));
    if (scale === 1 && file.size <= 1000000) {
      bitmap.close();
      return file;
    }
    const canvas = document.createElement('canvas');
    canvas.width = Math.max(1, Math.round(bitmap.width * scale));
    canvas.height = Math.max(1, Math.round(bitmap.height * scale));
    canvas.getContext('2d').drawImage(bitmap, 0, 0, canvas.width, canvas.height);
    bitmap.close();
    const blob = await new Promise((resolve) => canvas.toBlob(resolve, 'image/jpeg', 0.9));
    return blob || file;
  } catch (e) {
    return file;
  }
}

async function ask(file) {
  const status = $('answer-status');
  $('answer').replaceChildren();
  status.dataset.state = 'asking';
  status.textContent = 'Asking the map...';
  const photo = await shrink(file);
  $('mine').src = URL.createObjectURL(photo);  // change boxes are in the sent photo's pixels
  try {
    const response = await fetch('/v1/query', {
      method: 'POST',
      headers: Object.assign({ 'Content-Type': photo.type || 'application/octet-stream' }, authHeaders()),
      body: photo,
    });
    if (!response.ok) {
      status.dataset.state = 'error';
      status.textContent = 'Error: ' + await errorOf(response);
      return;
    }
    const answer = await response.json();
    status.dataset.state = 'done';
    status.textContent = 'Answered in ' + answer.latency_ms.toFixed(0) + ' ms (' +
        answer.objects + ' objects in your photo).';
    showAnswer(answer);
  } catch (e) {
    status.dataset.state = 'error';
    status.textContent = 'Error: the gateway cannot be reached (' + e + ')';
  }
}

async function refreshSite() {
  if (!token) return;
  const response = await fetch('/v1/site', { headers: authHeaders() }).catch(() => null);
  if (!response || !response.ok) {
    $('site-status').textContent = response ? 'Site overview: ' + await errorOf(response)
                                            : 'The gateway cannot be reached.';
    return;
  }
  const site = await response.json();
  const s = site.server;
  $('site-status').textContent = s
      ? s.map_places + ' places, ' + s.map_landmarks + ' landmarks; ' + s.robots +
        ' robots since start-up; ' + s.frames_per_second.toFixed(1) + ' frames/s; server ' +
        s.version + ', up ' + Math.round(s.uptime_s) + ' s'
      : 'No heartbeat from the server yet.';
  $('robots').replaceChildren(...(site.robots.length
      ? site.robots.map((r) => text('li', r.robot + ': ' + r.frames + ' answers heard'))
      : [text('li', 'None heard since the gateway started.', 'hint')]));
  const rows = site.loop_closures.map((c) => {
    const row = document.createElement('tr');
    row.append(text('td', c.robot), text('td', '#' + c.sequence + ' ' + when(c.utime)),
               text('td', c.place.robot + ' #' + c.place.sequence + ' ' + when(c.place.utime)),
               text('td', c.place.score.toFixed(0)));
    return row;
  });
  if (!rows.length) {
    const row = document.createElement('tr');
    const cell = text('td', 'None heard since the gateway started.', 'hint');
    cell.colSpan = 4;
    row.append(cell);
    rows.push(row);
  }
  $('loop-closures').tBodies[0].replaceChildren(...rows);
  showAlarms(site.alarms || []);
}

// Alarm pictures need the token, so they are fetched once each and kept as object URLs while
// their alarm is listed (alarm ids never repeat, even across the gateway's restarts). A fetch
// that failed (e.g. over the rate) is tried again at the next refresh.
const alarmPictures = new Map();
async function alarmPicture(path) {
  if (!path) return null;
  if (!alarmPictures.has(path)) {
    const url = fetch(path, { headers: authHeaders() })
        .then((r) => (r.ok ? r.blob() : null))
        .then((blob) => (blob ? URL.createObjectURL(blob) : null))
        .catch(() => null);
    alarmPictures.set(path, url);
    url.then((u) => { if (!u && alarmPictures.get(path) === url) alarmPictures.delete(path); });
  }
  return alarmPictures.get(path);
}

// Lets go of the pictures of alarms no longer listed.
function forgetAlarmPictures(alarms) {
  const listed = new Set();
  for (const a of alarms) listed.add(a.frame_picture).add(a.place_picture);
  for (const [path, url] of alarmPictures) {
    if (listed.has(path)) continue;
    alarmPictures.delete(path);
    url.then((u) => { if (u) URL.revokeObjectURL(u); });
  }
}

function showAlarms(alarms) {
  forgetAlarmPictures(alarms);
  const rows = alarms.map((a) => {
    const row = document.createElement('tr');
    const pictures = document.createElement('td');
    for (const path of [a.frame_picture, a.place_picture]) {
      alarmPicture(path).then((url) => {
        if (!url) return;
        const img = document.createElement('img');
        img.className = 'alarm-picture';
        img.src = url;
        img.alt = path === a.frame_picture ? 'the frame' : 'the stored place';
        pictures.append(img);
      });
    }
    row.append(text('td', a.robot), text('td', '#' + a.sequence + ' ' + when(a.utime)),
               text('td', describeChange(a)),
               text('td', '#' + a.place.place_id + ' (' + a.place.robot + ', ' +
                    when(a.place.utime) + ')'),
               pictures);
    return row;
  });
  if (!rows.length) {
    const row = document.createElement('tr');
    const cell = text('td', 'None heard since the gateway started.', 'hint');
    cell.colSpan = 5;
    row.append(cell);
    rows.push(row);
  }
  $('alarms').tBodies[0].replaceChildren(...rows);
}

$('save-token').addEventListener('click', () => { setToken($('token').value); refreshSite(); });
$('photo').addEventListener('change', (event) => {
  if (event.target.files.length) ask(event.target.files[0]);
});

const fromUrl = new URLSearchParams(location.hash.slice(1)).get('token');
setToken(fromUrl || localStorage.getItem('placerec-token') || '');
if (fromUrl) history.replaceState(null, '', location.pathname);  // keep it out of the history
refreshSite();
setInterval(refreshSite, 5000);
