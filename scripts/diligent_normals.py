#!/usr/bin/env python3
"""Normals of lightstage on the DiLiGenT objects in ../shared/data/diligent, as shared (cropped to
the object) and put back into their whole 612x512 frame (the crop where CROP.txt says, the rest
black): mean angular error over the mask against Normal_gt.mat, for `fit` and `normals`, and their
times; and whether each confidence map predicts the error (the mean error by quarter of confidence,
and their rank correlation). The two frames must agree (issue 49: the answer may not depend on empty
pixels around the object).

    PYTHONPATH=build/python python3 scripts/diligent_normals.py ball reading
"""
import os
import re
import shutil
import struct
import sys
import tempfile
import time
import zlib

import numpy as np
import scipy.io
import scipy.stats

import lightstage as ls

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', 'shared', 'data',
                    'diligent')
WHOLE = (512, 612)  # The benchmark's frame, rows x columns.


def read_codes(path):
    """A 16-bit PNG as its integer codes (lightstage reads it as linear floats in [0, 1])."""
    return np.round(np.asarray(ls.read_image(path)[0]) * 65535).astype(np.uint16)


def write_png16(path, codes):
    """A 16-bit grey or RGB PNG (filter 0 on every row, zlib)."""
    if codes.ndim == 2:
        codes = codes[..., None]
    height, width, channels = codes.shape
    raw = b''.join(b'\x00' + codes[y].astype('>u2').tobytes() for y in range(height))

    def chunk(kind, data):
        return struct.pack('>I', len(data)) + kind + data + struct.pack('>I', zlib.crc32(kind + data))

    colour = {1: 0, 3: 2, 4: 6}[channels]
    header = struct.pack('>IIBBBBB', width, height, 16, colour, 0, 0, 0)
    with open(path, 'wb') as out:
        out.write(b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', header) +
                  chunk(b'IDAT', zlib.compress(raw, 6)) + chunk(b'IEND', b''))


def crop_box(folder):
    text = open(os.path.join(folder, 'CROP.txt')).read()
    r0, r1, c0, c1 = map(int, re.findall(r'rows (\d+)\.\.(\d+), columns (\d+)\.\.(\d+)', text)[0])
    return r0, r1 + 1, c0, c1 + 1


def put_back_in_frame(folder, out):
    """The object's folder with every image (and mask) placed in its whole frame."""
    r0, r1, c0, c1 = crop_box(folder)
    os.makedirs(out, exist_ok=True)
    for name in os.listdir(folder):
        path = os.path.join(folder, name)
        if name.endswith('.png'):
            codes = read_codes(path)
            whole = np.zeros(WHOLE + codes.shape[2:], np.uint16)
            whole[r0:r1, c0:c1] = codes
            write_png16(os.path.join(out, name), whole)
        elif name != 'Normal_gt.mat':
            shutil.copy(path, out)


def angular_errors(maps, truth):
    """Per pixel, degrees between the estimated normal and the ground truth."""
    normal = np.asarray(maps['normal'], np.float64)
    normal /= np.maximum(np.linalg.norm(normal, axis=2, keepdims=True), 1e-12)
    cosine = np.clip((normal * truth).sum(axis=2), -1, 1)
    return np.degrees(np.arccos(cosine))


def angular_error(maps, truth, mask):
    return float(angular_errors(maps, truth)[mask].mean())


def error_by_confidence(maps, truth, mask, parts=4):
    """Whether the confidence map predicts the error: the mean error over each quarter of the mask's
    pixels ordered by confidence (lowest first), and the rank correlation of confidence and error
    (negative: the error is larger where the confidence is lower)."""
    errors = angular_errors(maps, truth)[mask]
    confidence = np.asarray(maps['confidence'], np.float64).reshape(mask.shape)[mask]
    order = np.argsort(confidence, kind='stable')
    means = [float(errors[part].mean()) for part in np.array_split(order, parts)]
    return means, float(scipy.stats.spearmanr(confidence, errors)[0])


def main(objects):
    work = tempfile.mkdtemp(prefix='diligent_')
    print(f'{"object":8s} {"frame":8s} {"fit deg":>8s} {"normals":>8s} {"fit s":>6s}')
    for name in objects:
        folder = os.path.join(DATA, name)
        truth = scipy.io.loadmat(os.path.join(folder, 'Normal_gt.mat'))['Normal_gt']
        mask = read_codes(os.path.join(folder, 'mask.png'))
        mask = mask.reshape(mask.shape[0], mask.shape[1], -1)[..., 0] > 0
        whole = os.path.join(work, name + '_whole')
        put_back_in_frame(folder, whole)
        r0, r1, c0, c1 = crop_box(folder)
        for frame, source in (('cropped', folder), ('whole', whole)):
            field = os.path.join(work, f'{name}_{frame}.exr')
            ls.import_set(source, out=field)
            start = time.time()
            fitted = ls.fit(field, out=os.path.join(work, f'{name}_{frame}_maps.exr'))
            seconds = time.time() - start
            normals = ls.normals(field, out=os.path.join(work, f'{name}_{frame}_normals.exr'))
            if frame == 'whole':
                fitted, normals = ({key: np.asarray(maps[key])[r0:r1, c0:c1]
                                    for key in ('normal', 'confidence')}
                                   for maps in (fitted, normals))
            print(f'{name:8s} {frame:8s} {angular_error(fitted, truth, mask):8.2f} '
                  f'{angular_error(normals, truth, mask):8.2f} {seconds:6.2f}')
            for method, maps in (('fit', fitted), ('normals', normals)):
                means, rank = error_by_confidence(maps, truth, mask)
                print(f'         {method:8s} error by confidence quarter (lowest first): ' +
                      ' '.join(f'{m:.2f}' for m in means) + f' deg; rank correlation {rank:+.2f}')
    shutil.rmtree(work)


if __name__ == '__main__':
    main(sys.argv[1:] or ['ball', 'reading'])
