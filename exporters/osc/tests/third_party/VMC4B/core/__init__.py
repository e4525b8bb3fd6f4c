if "bpy" not in locals():
    import bpy
    from . import state
    from . import config
    from . import applier
    from . import recorder
    from . import server
    from . import utility
else:
    import importlib
    importlib.reload(state)
    importlib.reload(config)
    importlib.reload(applier)
    importlib.reload(recorder)
    importlib.reload(server)
    importlib.reload(utility)
