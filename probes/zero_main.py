def derivative_kernel(w, at, out, step, k, layout, drive, scratch, kinematic, record):
    for j in range(13):
        w[out + j * step] = 0.0
    if record >= 0:
        for j in range(9):
            w[record + j * step] = 0.0
