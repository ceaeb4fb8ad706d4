"""What every figure family shares: the axes to draw on."""


def get_axes(ax=None, figsize=(7.0, 4.0), projection=None):
    """`ax` itself, or the axes of a new figure of `figsize` [in] (constrained layout)."""
    if ax is not None:
        return ax
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=figsize, layout="constrained")
    return fig.add_subplot(projection=projection)
